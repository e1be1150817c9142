#pragma once

// render.v1.WorkerService over the JobManager.

#include "render.grpc.pb.h"
#include "server/auth.h"
#include "server/job_manager.h"
#include "server/report_forwarder.h"
#include "server/stream_guard.h"

namespace render::server {

class WorkerServiceImpl final : public v1::WorkerService::Service {
  public:
    // `forwarder`: where reports for leases another server of a shared store granted go (null:
    // they are dropped).
    WorkerServiceImpl(JobManager& manager, const Auth& auth, ReportForwarder* forwarder = nullptr)
        : manager_(manager), auth_(auth), forwarder_(forwarder) {}

    grpc::Status RegisterWorker(grpc::ServerContext* context,
                                const v1::RegisterWorkerRequest* request,
                                v1::RegisterWorkerReply* reply) override;
    grpc::Status Lease(grpc::ServerContext* context, const v1::LeaseRequest* request,
                       v1::LeaseReply* reply) override;
    grpc::Status FetchAsset(grpc::ServerContext* context, const v1::FetchAssetRequest* request,
                            grpc::ServerWriter<v1::AssetChunk>* writer) override;
    grpc::Status FetchMask(grpc::ServerContext* context, const v1::FetchMaskRequest* request,
                           grpc::ServerWriter<v1::MaskChunk>* writer) override;
    grpc::Status Heartbeat(grpc::ServerContext* context, const v1::HeartbeatRequest* request,
                           v1::HeartbeatReply* reply) override;
    grpc::Status Report(grpc::ServerContext* context, grpc::ServerReader<v1::ReportChunk>* reader,
                        v1::ReportReply* reply) override;

  private:
    // Reads the rest of a report this server did not grant and sends it to the job's holder.
    grpc::Status forward_report(const std::string& holder, size_t max_value_bytes,
                                v1::ReportChunk&& header_chunk,
                                grpc::ServerReader<v1::ReportChunk>* reader,
                                std::unique_ptr<StreamGuards::Guard>& guard,
                                v1::ReportReply* reply);

    JobManager& manager_;
    const Auth& auth_;
    ReportForwarder* forwarder_;
};

}  // namespace render::server
