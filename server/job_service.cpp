#include "server/job_service.h"

#include <algorithm>
#include <chrono>
#include <fstream>
#include <thread>

#include "core/base/memory_budget.h"
#include "core/util/log.h"
#include "core/util/sha256.h"
#include "server/validation.h"

namespace render::server {

using grpc::Status;
using grpc::StatusCode;

namespace {
constexpr size_t kChunk = 1 << 20;
}

Status stream_file(const std::filesystem::path& file,
                   const std::function<bool(std::string&&, uint64_t)>& send) {
    std::ifstream in(file, std::ios::binary);
    if (!in) return Status(StatusCode::NOT_FOUND, "cannot open " + file.filename().string());
    in.seekg(0, std::ios::end);
    uint64_t total = uint64_t(in.tellg());
    in.seekg(0);
    uint64_t sent = 0;
    do {
        std::string data(size_t(std::min<uint64_t>(kChunk, total - sent)), '\0');
        if (!data.empty() && !in.read(data.data(), std::streamsize(data.size())))
            return Status(StatusCode::INTERNAL, "cannot read " + file.filename().string());
        sent += data.size();
        if (!send(std::move(data), total))
            return Status(StatusCode::CANCELLED, "the client went away");
    } while (sent < total);
    return Status::OK;
}

Status JobServiceImpl::UploadAsset(grpc::ServerContext* context,
                                   grpc::ServerReader<v1::AssetChunk>* reader,
                                   v1::BundleFile* reply) {
    if (Status s = auth_.check(context); !s.ok()) return s;
    Status refused;
    auto guard = manager_.client_streams().admit(context, "UploadAsset", &refused);
    if (!guard) return refused;
    v1::AssetChunk chunk;
    if (!reader->Read(&chunk)) {
        if (guard->timed_out()) return guard->idle_status();
        return Status(StatusCode::INVALID_ARGUMENT, "empty upload: no chunk received");
    }
    guard->progress();
    const std::string sha = chunk.sha256();
    const uint64_t size = chunk.size();
    if (!is_sha256_hex(sha))
        return Status(StatusCode::INVALID_ARGUMENT,
                      "the first chunk's sha256 must be 64 lower-case hex digits");
    if (size > kMaxAssetSize)
        return Status(StatusCode::RESOURCE_EXHAUSTED,
                      "asset of " + std::to_string(size) + " bytes exceeds the 4 GiB limit");
    // No job could use an asset larger than a job's bundle may be.
    const uint64_t job_limit = std::min(manager_.options().max_job_assets, kMaxBundleSize);
    if (size > job_limit)
        return Status(StatusCode::RESOURCE_EXHAUSTED,
                      "asset of " + std::to_string(size) +
                          " bytes exceeds the per-job size limit of " + std::to_string(job_limit) +
                          " bytes (server --max-job-assets " + format_bytes(job_limit) + ")");
    AssetStore::Upload upload(manager_.assets(), sha, size);
    // The store's total limit, reserved before a byte is written.
    if (std::string e = upload.reserve(); !e.empty()) {
        Log("warn", "upload_refused").kv("sha256", sha).kv("size", size).kv("error", e);
        return Status(StatusCode::RESOURCE_EXHAUSTED, e);
    }
    do {
        if (chunk.data().size() > kChunk + 1024)
            return Status(StatusCode::INVALID_ARGUMENT, "chunk larger than 1 MiB");
        if (!chunk.sha256().empty() && chunk.sha256() != sha)
            return Status(StatusCode::INVALID_ARGUMENT, "chunks name different assets");
        if (std::string e = upload.write(chunk.data()); !e.empty())
            return Status(StatusCode::INVALID_ARGUMENT, e);
        guard->progress();
    } while (reader->Read(&chunk));
    if (guard->timed_out()) return guard->idle_status();
    if (context->IsCancelled()) return Status(StatusCode::CANCELLED, "upload cancelled");
    if (std::string e = upload.commit(); !e.empty()) {
        Log("warn", "upload_rejected").kv("sha256", sha).kv("error", e);
        return Status(StatusCode::INVALID_ARGUMENT, e);
    }
    manager_.asset_added(sha, size);
    manager_.metrics().asset_received(size);
    Log("info", "asset_uploaded").kv("sha256", sha).kv("size", size);
    reply->set_sha256(sha);
    reply->set_size(size);
    return Status::OK;
}

Status JobServiceImpl::HasAssets(grpc::ServerContext* context, const v1::HasAssetsRequest* request,
                                 v1::HasAssetsReply* reply) {
    if (Status s = auth_.check(context); !s.ok()) return s;
    for (const std::string& sha : request->sha256())
        if (!is_sha256_hex(sha))
            return Status(StatusCode::INVALID_ARGUMENT,
                          "sha256 \"" + sha.substr(0, 80) + "\" is not 64 lower-case hex digits");
    manager_.has_assets(*request, reply);
    return Status::OK;
}

Status JobServiceImpl::SubmitJob(grpc::ServerContext* context, const v1::SubmitJobRequest* request,
                                 v1::Job* reply) {
    if (Status s = auth_.check(context); !s.ok()) return s;
    Status s = manager_.submit(*request, reply);
    if (!s.ok())
        Log("warn", "submit_rejected")
            .kv("code", int(s.error_code()))
            .kv("error", s.error_message());
    return s;
}

Status JobServiceImpl::GetJob(grpc::ServerContext* context, const v1::GetJobRequest* request,
                              v1::Job* reply) {
    if (Status s = auth_.check(context); !s.ok()) return s;
    return manager_.get(request->job_id(), reply);
}

Status JobServiceImpl::ListJobs(grpc::ServerContext* context, const v1::ListJobsRequest*,
                                v1::ListJobsReply* reply) {
    if (Status s = auth_.check(context); !s.ok()) return s;
    manager_.list(reply);
    return Status::OK;
}

Status JobServiceImpl::WatchJob(grpc::ServerContext* context, const v1::WatchJobRequest* request,
                                grpc::ServerWriter<v1::JobEvent>* writer) {
    if (Status s = auth_.check(context); !s.ok()) return s;
    if (watch_streams_.fetch_add(1) >= kMaxWatchStreams) {
        watch_streams_.fetch_sub(1);
        return Status(StatusCode::RESOURCE_EXHAUSTED,
                      "more than " + std::to_string(kMaxWatchStreams) +
                          " WatchJob streams are open on this server: poll GetJob instead");
    }
    struct Release {
        std::atomic<size_t>& open;
        ~Release() { open.fetch_sub(1); }
    } release{watch_streams_};
    // A watcher that stops reading blocks Write once the transport's window is full: it is
    // cancelled after --stream-idle-timeout seconds. Waiting for the job to change is the
    // server's doing and not idle: every poll counts as progress.
    Status refused;
    auto guard = manager_.long_streams().admit(context, "WatchJob", &refused);
    if (!guard) return refused;
    std::string last;
    while (!context->IsCancelled()) {
        guard->progress();
        v1::JobEvent event;
        if (Status s = manager_.get(request->job_id(), event.mutable_job()); !s.ok()) return s;
        std::string now = event.job().SerializeAsString();
        if (now != last) {
            if (!writer->Write(event))
                return guard->timed_out() ? guard->idle_status()
                                          : Status(StatusCode::CANCELLED, "watcher went away");
            last = std::move(now);
        }
        auto state = event.job().state();
        if (state == v1::JOB_STATE_DONE || state == v1::JOB_STATE_CANCELLED ||
            state == v1::JOB_STATE_FAILED)
            return Status::OK;
        for (int i = 0; i < 10 && !stopping_ && !context->IsCancelled(); ++i)
            std::this_thread::sleep_for(std::chrono::milliseconds(50));
        if (stopping_) return Status(StatusCode::UNAVAILABLE, "the server is shutting down");
    }
    return Status(StatusCode::CANCELLED, "watcher went away");
}

Status JobServiceImpl::DeleteJob(grpc::ServerContext* context, const v1::DeleteJobRequest* request,
                                 v1::DeleteJobReply* reply) {
    if (Status s = auth_.check(context); !s.ok()) return s;
    return manager_.delete_job(request->job_id(), reply);
}

Status JobServiceImpl::CancelJob(grpc::ServerContext* context, const v1::CancelJobRequest* request,
                                 v1::Job* reply) {
    if (Status s = auth_.check(context); !s.ok()) return s;
    return manager_.cancel(request->job_id(), reply);
}

Status JobServiceImpl::FetchResult(grpc::ServerContext* context,
                                   const v1::FetchResultRequest* request,
                                   grpc::ServerWriter<v1::ResultChunk>* writer) {
    if (Status s = auth_.check(context); !s.ok()) return s;
    Status refused;
    auto guard = manager_.client_streams().admit(context, "FetchResult", &refused);
    if (!guard) return refused;
    std::filesystem::path file;
    bool temporary = false;
    if (Status s = manager_.result_file(*request, &file, &temporary); !s.ok()) return s;
    Status s = stream_file(file, [&](std::string&& data, uint64_t total) {
        v1::ResultChunk chunk;
        chunk.set_data(std::move(data));
        chunk.set_total_size(total);
        if (!writer->Write(chunk)) return false;
        guard->progress();
        return true;
    });
    if (!s.ok() && guard->timed_out()) s = guard->idle_status();
    if (temporary) {
        std::error_code ec;
        std::filesystem::remove(file, ec);
    }
    return s;
}

Status JobServiceImpl::ClusterStatus(grpc::ServerContext* context, const v1::ClusterStatusRequest*,
                                     v1::ClusterStatusReply* reply) {
    if (Status s = auth_.check(context); !s.ok()) return s;
    manager_.cluster_status(reply);
    return Status::OK;
}

}  // namespace render::server
