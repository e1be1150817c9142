#pragma once

// render.v1.WorkerService over the JobManager.

#include "render.grpc.pb.h"
#include "server/auth.h"
#include "server/job_manager.h"

namespace render::server {

class WorkerServiceImpl final : public v1::WorkerService::Service {
  public:
    WorkerServiceImpl(JobManager& manager, const Auth& auth) : manager_(manager), auth_(auth) {}

    grpc::Status RegisterWorker(grpc::ServerContext* context,
                                const v1::RegisterWorkerRequest* request,
                                v1::RegisterWorkerReply* reply) override;
    grpc::Status Lease(grpc::ServerContext* context, const v1::LeaseRequest* request,
                       v1::LeaseReply* reply) override;
    grpc::Status FetchAsset(grpc::ServerContext* context, const v1::FetchAssetRequest* request,
                            grpc::ServerWriter<v1::AssetChunk>* writer) override;
    grpc::Status Heartbeat(grpc::ServerContext* context, const v1::HeartbeatRequest* request,
                           v1::HeartbeatReply* reply) override;
    grpc::Status Report(grpc::ServerContext* context, grpc::ServerReader<v1::ReportChunk>* reader,
                        v1::ReportReply* reply) override;

  private:
    JobManager& manager_;
    const Auth& auth_;
};

}  // namespace render::server
