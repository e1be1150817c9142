#pragma once

// The client's connection to the server (address, token, stub) and a failed call on it.

#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "render.grpc.pb.h"
#include "service/rpc.h"
#include "service/transport_security.h"

namespace render::service {

constexpr double kRpcTimeout = 30.0;

struct RpcFailure : std::runtime_error {
    RpcFailure(const std::string& call, const grpc::Status& s)
        : std::runtime_error(call + " failed: " + describe(s)), status(s) {}
    grpc::Status status;
};

struct Connection {
    mutable std::string address;  // the server in use (fail_over changes it)
    std::string token;
    // Several servers of one farm (--server A,B; docs/guide/service.md, "Several servers"):
    // the list, and the TLS setup to connect to another of them.
    std::vector<std::string> addresses;
    ClientTls tls;
    // Mutable: fail_over replaces it on a Connection passed by const reference.
    mutable std::unique_ptr<v1::JobService::Stub> stub;

    void prepare(grpc::ClientContext& context, double timeout = kRpcTimeout) const {
        prepare_context(context, token, timeout);
    }
    // The server in use could not be reached: moves to the next of the list that answers
    // within a few seconds (else simply the next). False with a single server.
    bool fail_over() const;

  private:
    mutable size_t index_ = 0;
    friend std::optional<Connection> connect_to_server(const std::string&, const std::string&,
                                                       const std::string&, const std::string&);
};

// The connection the global options ask for (`server`: one HOST:PORT or a comma-separated list,
// of which the first that answers is used; empty options fall back to the environment:
// RENDER_TOKEN, RENDER_TLS_CA, RENDER_TLS_SERVER_NAME). Nothing, after printing the problem,
// for an unusable TLS setup or a token that would travel in clear.
std::optional<Connection> connect_to_server(const std::string& server, const std::string& token,
                                            const std::string& tls_ca,
                                            const std::string& tls_server_name);

// Whether the channel is TLS: --tls-ca or env RENDER_TLS_CA.
bool tls_used(const std::string& tls_ca_flag);

// A hint for a server that cannot be reached: a TLS mismatch shows up as UNAVAILABLE.
std::string connection_hint(const grpc::Status& status, bool tls);

v1::Job get_job(const Connection& c, const std::string& job_id);

}  // namespace render::service
