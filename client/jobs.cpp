// `client list`, `status`, `cancel` and `delete`: one call each, printed as a table or a line.

#include <chrono>
#include <cstdio>
#include <ctime>

#include "client/commands.h"
#include "client/progress.h"
#include "core/base/memory_budget.h"

namespace render::service {
namespace {

std::string format_time(int64_t unix_ms) {
    if (unix_ms <= 0) return "-";
    std::time_t t = std::time_t(unix_ms / 1000);
    std::tm tm{};
    localtime_r(&t, &tm);
    char buf[32];
    std::strftime(buf, sizeof buf, "%Y-%m-%d %H:%M:%S", &tm);
    return buf;
}

}  // namespace

int list(const Connection& c) {
    grpc::ClientContext context;
    c.prepare(context);
    v1::ListJobsReply reply;
    grpc::Status status = c.stub->ListJobs(&context, v1::ListJobsRequest(), &reply);
    if (!status.ok()) throw RpcFailure("ListJobs", status);
    std::printf("%-24s %-10s %4s %-5s %7s %14s  %-19s  %s\n", "ID", "STATE", "PRIO", "ALGO",
                "FRAMES", "ITERATIONS", "SUBMITTED", "NAME");
    for (const v1::Job& job : reply.jobs()) {
        uint64_t done = 0, target = 0;
        int frames_done = 0;
        for (const auto& f : job.frames()) {
            done += f.iterations_done();
            target += f.iterations_target();
            frames_done += f.done();
        }
        std::string frames = std::to_string(frames_done) + "/" + std::to_string(job.frames_size());
        std::string its = std::to_string(done) + "/" + (target ? std::to_string(target) : "-");
        std::printf("%-24s %-10s %4d %-5s %7s %14s  %-19s  %s\n", job.id().c_str(),
                    state_name(job.state()), job.priority(), job.settings().algorithm().c_str(),
                    frames.c_str(), its.c_str(), format_time(job.submitted_unix_ms()).c_str(),
                    job.name().c_str());
        if (!job.waiting().empty()) std::printf("%-24s %s\n", "", job.waiting().c_str());
    }
    return 0;
}

int status(const Connection& c) {
    grpc::ClientContext context;
    c.prepare(context);
    v1::ClusterStatusReply reply;
    grpc::Status s = c.stub->ClusterStatus(&context, v1::ClusterStatusRequest(), &reply);
    if (!s.ok()) throw RpcFailure("ClusterStatus", s);
    std::printf("server %s: %u queued, %u running, %u waiting for memory job(s), %d worker(s)\n",
                c.address.c_str(), reply.queued_jobs(), reply.running_jobs(), reply.waiting_jobs(),
                reply.workers_size());
    if (reply.workers_size() > 0)
        std::printf("%-24s %-20s %7s %10s  %s\n", "WORKER", "HOST", "THREADS", "SEEN", "LEASE");
    int64_t now = std::chrono::duration_cast<std::chrono::milliseconds>(
                      std::chrono::system_clock::now().time_since_epoch())
                      .count();
    for (const v1::WorkerStatus& w : reply.workers()) {
        std::string seen =
            w.last_seen_unix_ms() > 0
                ? render::format_seconds((now - w.last_seen_unix_ms()) / 1000.0) + " ago"
                : "-";
        std::printf("%-24s %-20s %7u %10s  %s\n", w.worker_id().c_str(), w.host().c_str(),
                    w.threads(), seen.c_str(),
                    w.lease_id().empty() ? "idle" : w.lease_id().c_str());
    }
    return 0;
}

int cancel(const Connection& c, const std::string& job_id) {
    grpc::ClientContext context;
    c.prepare(context);
    v1::CancelJobRequest request;
    request.set_job_id(job_id);
    v1::Job job;
    grpc::Status s = c.stub->CancelJob(&context, request, &job);
    if (!s.ok()) throw RpcFailure("CancelJob", s);
    std::printf("job %s: %s\n", job.id().c_str(), state_name(job.state()));
    return 0;
}

int delete_job(const Connection& c, const std::string& job_id) {
    grpc::ClientContext context;
    c.prepare(context);
    v1::DeleteJobRequest request;
    request.set_job_id(job_id);
    v1::DeleteJobReply reply;
    grpc::Status s = c.stub->DeleteJob(&context, request, &reply);
    if (!s.ok()) throw RpcFailure("DeleteJob", s);
    std::printf("job %s deleted: %llu asset(s) no other job uses removed, %s freed\n",
                job_id.c_str(), (unsigned long long)reply.assets_removed(),
                render::format_bytes(reply.bytes_freed()).c_str());
    return 0;
}

}  // namespace render::service
