#include "client/connection.h"

#include <chrono>
#include <cstdio>
#include <stdexcept>

#include "service/server_list.h"

namespace render::service {

namespace {

// How long a server of a list has to answer before the next one is tried.
constexpr double kProbeSeconds = 3.0;

bool answers(const std::shared_ptr<grpc::Channel>& channel) {
    return channel->WaitForConnected(std::chrono::system_clock::now() +
                                     std::chrono::milliseconds(int64_t(kProbeSeconds * 1000)));
}

}  // namespace

std::optional<Connection> connect_to_server(const std::string& server, const std::string& token,
                                            const std::string& tls_ca,
                                            const std::string& tls_server_name) {
    Connection c;
    c.token = token_or_env(token);
    try {
        c.addresses = split_server_list(server);
    } catch (const std::invalid_argument& e) {
        std::fprintf(stderr, "client: --server: %s\n", e.what());
        return std::nullopt;
    }
    try {
        c.tls = client_tls_from(tls_ca, tls_server_name);
    } catch (const std::runtime_error& e) {
        std::fprintf(stderr, "client: %s\n", e.what());
        return std::nullopt;
    }
    for (const std::string& address : c.addresses)
        if (const std::string problem =
                check_client_transport(address, c.tls.tls, !c.token.empty());
            !problem.empty()) {
            std::fprintf(stderr, "client: %s\n", problem.c_str());
            return std::nullopt;
        }
    // With several servers, the first that answers; one server is used as given (a call to a
    // server that is down fails with UNAVAILABLE, as it always did).
    c.index_ = 0;
    if (c.addresses.size() > 1)
        for (size_t i = 0; i < c.addresses.size(); ++i)
            if (answers(make_channel(c.addresses[i], c.tls))) {
                c.index_ = i;
                break;
            }
    c.address = c.addresses[c.index_];
    c.stub = v1::JobService::NewStub(make_channel(c.address, c.tls));
    return c;
}

bool Connection::fail_over() const {
    if (addresses.size() < 2) return false;
    size_t next = (index_ + 1) % addresses.size();
    for (size_t tried = 1; tried < addresses.size(); ++tried) {
        const size_t i = (index_ + tried) % addresses.size();
        if (answers(make_channel(addresses[i], tls))) {
            next = i;
            break;
        }
    }
    std::fprintf(stderr, "client: server %s unreachable, using %s\n", addresses[index_].c_str(),
                 addresses[next].c_str());
    index_ = next;
    address = addresses[next];
    stub = v1::JobService::NewStub(make_channel(addresses[next], tls));
    return true;
}

bool tls_used(const std::string& tls_ca_flag) {
    return !flag_or_env(tls_ca_flag, "RENDER_TLS_CA").empty();
}

std::string connection_hint(const grpc::Status& status, bool tls) {
    if (status.error_code() != grpc::StatusCode::UNAVAILABLE) return "";
    return tls ? "\nclient: with --tls-ca the server must serve TLS (--tls-cert/--tls-key) with a "
                 "certificate signed by that CA for the host of --server (or for "
                 "--tls-server-name)"
               : "\nclient: if the server serves TLS (--tls-cert/--tls-key), give --tls-ca FILE";
}

v1::Job get_job(const Connection& c, const std::string& job_id) {
    grpc::ClientContext context;
    c.prepare(context);
    v1::GetJobRequest request;
    request.set_job_id(job_id);
    v1::Job job;
    grpc::Status status = c.stub->GetJob(&context, request, &job);
    if (!status.ok()) throw RpcFailure("GetJob", status);
    return job;
}

}  // namespace render::service
