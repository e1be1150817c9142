#include "server/report_forwarder.h"

#include "service/rpc.h"

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
    service::ClientTls tls;
    tls.tls = !tls_root_pem_.empty();
    tls.root_certs = tls_root_pem_;
    grpc::ChannelArguments args;
    // A report is as large as its frame's sums (the workers' limit, not gRPC's default 4 MB).
    args.SetMaxSendMessageSize(-1);
    auto made = grpc::CreateCustomChannel(address, service::channel_credentials(tls), args);
    channels_[address] = made;
    return made;
}

grpc::Status ReportForwarder::forward(const std::string& address,
                                      const std::vector<v1::ReportChunk>& chunks,
                                      v1::ReportReply* reply) {
    auto stub = v1::WorkerService::NewStub(channel(address));
    grpc::ClientContext context;
    context.AddMetadata(kForwardedKey, "1");
    // The worker waits for this answer; a holder that does not answer within a minute is
    // treated as unreachable (the worker then gives the report up, as before).
    service::prepare_context(context, token_, 60);
    auto writer = stub->Report(&context, reply);
    for (const v1::ReportChunk& chunk : chunks)
        if (!writer->Write(chunk)) break;
    writer->WritesDone();
    return writer->Finish();
}

}  // namespace render::server
