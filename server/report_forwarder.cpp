#include "server/report_forwarder.h"

#include <chrono>

namespace render::server {

ReportForwarder::ReportForwarder(std::string token, std::string tls_root_pem)
    : token_(std::move(token)), tls_root_pem_(std::move(tls_root_pem)) {}

bool ReportForwarder::forwarded(const grpc::ServerContext& context) {
    return context.client_metadata().count(kForwardedKey) > 0;
}

std::shared_ptr<grpc::Channel> ReportForwarder::channel(const std::string& address) {
    std::lock_guard lock(mu_);
    auto it = channels_.find(address);
    if (it != channels_.end()) return it->second;
    std::shared_ptr<grpc::ChannelCredentials> credentials;
    if (tls_root_pem_.empty()) {
        credentials = grpc::InsecureChannelCredentials();
    } else {
        grpc::SslCredentialsOptions ssl;
        ssl.pem_root_certs = tls_root_pem_;
        credentials = grpc::SslCredentials(ssl);
    }
    grpc::ChannelArguments args;
    // A report is as large as its frame's sums (the workers' limit, not gRPC's default 4 MB).
    args.SetMaxSendMessageSize(-1);
    auto made = grpc::CreateCustomChannel(address, credentials, args);
    channels_[address] = made;
    return made;
}

grpc::Status ReportForwarder::forward(const std::string& address,
                                      const std::vector<v1::ReportChunk>& chunks,
                                      v1::ReportReply* reply) {
    auto stub = v1::WorkerService::NewStub(channel(address));
    grpc::ClientContext context;
    context.AddMetadata(kForwardedKey, "1");
    if (!token_.empty()) context.AddMetadata("authorization", "Bearer " + token_);
    // The worker waits for this answer; a holder that does not answer within a minute is
    // treated as unreachable (the worker then gives the report up, as before).
    context.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(60));
    auto writer = stub->Report(&context, reply);
    for (const v1::ReportChunk& chunk : chunks)
        if (!writer->Write(chunk)) break;
    writer->WritesDone();
    return writer->Finish();
}

}  // namespace render::server
