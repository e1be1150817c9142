#pragma once

// render.v1.JobService over the JobManager.

#include <atomic>

#include "render.grpc.pb.h"
#include "server/auth.h"
#include "server/job_manager.h"

namespace render::server {

class JobServiceImpl final : public v1::JobService::Service {
  public:
    JobServiceImpl(JobManager& manager, const Auth& auth, const std::atomic<bool>& stopping)
        : manager_(manager), auth_(auth), stopping_(stopping) {}

    grpc::Status UploadAsset(grpc::ServerContext* context,
                             grpc::ServerReader<v1::AssetChunk>* reader,
                             v1::BundleFile* reply) override;
    grpc::Status HasAssets(grpc::ServerContext* context, const v1::HasAssetsRequest* request,
                           v1::HasAssetsReply* reply) override;
    grpc::Status SubmitJob(grpc::ServerContext* context, const v1::SubmitJobRequest* request,
                           v1::Job* reply) override;
    grpc::Status GetJob(grpc::ServerContext* context, const v1::GetJobRequest* request,
                        v1::Job* reply) override;
    grpc::Status ListJobs(grpc::ServerContext* context, const v1::ListJobsRequest* request,
                          v1::ListJobsReply* reply) override;
    grpc::Status WatchJob(grpc::ServerContext* context, const v1::WatchJobRequest* request,
                          grpc::ServerWriter<v1::JobEvent>* writer) override;
    grpc::Status DeleteJob(grpc::ServerContext* context, const v1::DeleteJobRequest* request,
                           v1::DeleteJobReply* reply) override;
    grpc::Status CancelJob(grpc::ServerContext* context, const v1::CancelJobRequest* request,
                           v1::Job* reply) override;
    grpc::Status FetchResult(grpc::ServerContext* context, const v1::FetchResultRequest* request,
                             grpc::ServerWriter<v1::ResultChunk>* writer) override;
    grpc::Status ClusterStatus(grpc::ServerContext* context,
                               const v1::ClusterStatusRequest* request,
                               v1::ClusterStatusReply* reply) override;

  private:
    JobManager& manager_;
    const Auth& auth_;
    const std::atomic<bool>& stopping_;
    std::atomic<size_t> watch_streams_{0};  // WatchJob streams open now (kMaxWatchStreams)
};

// Streams a file in chunks of at most 1 MiB through `send(data, total_size)`.
grpc::Status stream_file(const std::filesystem::path& file,
                         const std::function<bool(std::string&&, uint64_t)>& send);

}  // namespace render::server
