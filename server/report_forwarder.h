#pragma once

// Reports that reach a server which did not grant their lease, forwarded to the server that
// holds the lease's job on a shared store (docs/design/job-store.md, "Reports reaching a
// non-holder"): a worker that failed over to another server of the farm while its lease's
// holder lives keeps its rendered range instead of having it leased again.

#include <grpcpp/grpcpp.h>

#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "render.grpc.pb.h"

namespace render::server {

class ReportForwarder {
  public:
    // The metadata key a forwarded report carries: a server never forwards it again (a holder
    // that does not know the lease drops it), so a report crosses at most one hop.
    static constexpr const char* kForwardedKey = "render-forwarded";

    // `token`: the farm's bearer token (every server of one farm has the same); `tls_root_pem`:
    // empty for plaintext, else the certificate the holders present (the farm's servers share
    // one) or the authority that signed it.
    ReportForwarder(std::string token, std::string tls_root_pem);

    // Whether the call came from another server's forwarder.
    static bool forwarded(const grpc::ServerContext& context);

    // Sends the report (its header chunk, then its value chunks as received) to the server at
    // `address` and returns its status; `reply` receives the holder's answer.
    grpc::Status forward(const std::string& address, const std::vector<v1::ReportChunk>& chunks,
                         v1::ReportReply* reply);

  private:
    std::shared_ptr<grpc::Channel> channel(const std::string& address);

    std::string token_;
    std::string tls_root_pem_;
    std::mutex mu_;
    std::map<std::string, std::shared_ptr<grpc::Channel>> channels_;
};

}  // namespace render::server
