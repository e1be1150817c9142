// The job manager's housekeeping: deleting finished jobs (on request or by the retention rule)
// and sweeping assets no job references (docs/guide/service.md, "Deleting jobs").

#include "server/job_manager.h"

#include <algorithm>
#include <chrono>

#include "core/util/log.h"
#include "server/job_manager_detail.h"

namespace render::server {

namespace fs = std::filesystem;
using grpc::Status;
using grpc::StatusCode;
using namespace detail;

void JobManager::tick() {
    if (shared_) sync_shared(false);
    delete_reported_leases();
    advance();
    flush_checkpoints(false);
    apply_retention();
    collect_unreferenced_assets();
}

void JobManager::delete_reported_leases() {
    std::vector<std::string> ids;
    {
        std::lock_guard lock(reported_mu_);
        ids.swap(reported_leases_);
    }
    if (ids.empty()) return;
    // On failure (the database away) the rows stay: harmless (reported_leases_ above) and
    // voided with the job's others by its next holder, or at the next start of one server.
    store_or_log("leases", std::to_string(ids.size()), [&] { store_.delete_leases(ids); });
}

Status JobManager::delete_job(const std::string& job_id, v1::DeleteJobReply* reply,
                              const char* reason) {
    // One frame finishes at a time (finish_mu_): none of this job's is being written now.
    std::lock_guard finish_lock(finish_mu_);
    std::vector<std::string> orphans;
    {
        std::lock_guard lock(mu_);
        auto job = find(job_id);
        if (!job) return job_not_found(job_id);
        if (!is_terminal(scheduler_.state(job_id)))
            return Status(StatusCode::FAILED_PRECONDITION,
                          "job " + job_id + " is still queued or running: cancel it first");
        std::set<std::string> mine;
        for (const v1::BundleFile& f : job->request.bundle().files()) mine.insert(f.sha256());
        for (const std::string& sha : assets_in_use(job_id)) mine.erase(sha);
        orphans.assign(mine.begin(), mine.end());
        scheduler_.remove_job(job_id);
        jobs_.erase(job_id);
        // The rows go while mu_ is held: a restart never sees a job whose files are gone.
        store_or_log("job", job_id, [&] { store_.delete_job(job_id, orphans); });
        // Removed under mu_ too; the assets a submit in progress names are pinned (passed
        // over above) from before it checks them until its job is stored.
        uint64_t freed = 0, removed = 0;
        for (const std::string& sha : orphans)
            if (const uint64_t n = assets_.remove(sha); n > 0) {
                freed += n;
                ++removed;
            }
        reply->set_assets_removed(removed);
        reply->set_bytes_freed(freed);
    }
    std::error_code ec;
    for (const fs::path& dir :
         {options_.store / "jobs" / job_id, options_.store / "checkpoints" / job_id,
          options_.store / "results" / job_id})
        fs::remove_all(dir, ec);
    Log("info", "job_deleted")
        .kv("job", job_id)
        .kv("reason", reason)
        .kv("assets_removed", reply->assets_removed())
        .kv("bytes_freed", reply->bytes_freed());
    return Status::OK;
}

void JobManager::apply_retention() {
    const double retain = options_.retain_finished_seconds;
    if (retain <= 0) return;
    std::vector<std::string> expired;
    {
        std::lock_guard lock(mu_);
        const int64_t cutoff = now_unix_ms() - int64_t(retain * 1000);
        for (const auto& [id, job] : jobs_)
            if (is_terminal(scheduler_.state(id)) && job->row.finished_unix_ms > 0 &&
                job->row.finished_unix_ms <= cutoff)
                expired.push_back(id);
    }
    // Each through DeleteJob's own code: the same rows, folders and unshared assets go.
    uint64_t deleted = 0, assets = 0, freed = 0;
    for (const std::string& id : expired) {
        v1::DeleteJobReply reply;
        // NOT_FOUND: a client deleted it meanwhile.
        if (!delete_job(id, &reply, "retention").ok()) continue;
        metrics_.job_expired();
        ++deleted;
        assets += reply.assets_removed();
        freed += reply.bytes_freed();
    }
    if (deleted > 0)
        Log("info", "retention")
            .kv("jobs_deleted", deleted)
            .kv("assets_removed", assets)
            .kv("bytes_freed", freed)
            .kv("retain_seconds", retain);
}

void JobManager::collect_unreferenced_assets() {
    const double grace = options_.unreferenced_asset_seconds;
    if (grace <= 0) return;
    const TimePoint now = clock_();
    const double every = std::clamp(grace / 4, 0.5, 60.0);
    if (last_asset_sweep_ &&
        std::chrono::duration<double>(now - *last_asset_sweep_).count() < every)
        return;
    last_asset_sweep_ = now;
    std::vector<std::string> removed;
    uint64_t freed = 0;
    {
        // Under mu_: a submit pins its assets under mu_ before it checks that they exist, and
        // stores its job under mu_, so every asset a job names or will name is seen here.
        std::lock_guard lock(mu_);
        const std::set<std::string> wanted = assets_in_use();
        const int64_t cutoff = now_unix_ms() - int64_t(grace * 1000);
        for (const std::string& sha : assets_.list()) {
            if (wanted.count(sha)) continue;
            if (const std::optional<uint64_t> n = assets_.remove_if_untouched_since(sha, cutoff)) {
                removed.push_back(sha);
                freed += *n;
                metrics_.asset_collected(*n);
                Log("info", "asset_collected").kv("sha256", sha).kv("bytes", *n);
            }
        }
        if (!removed.empty())
            store_or_log("assets", std::to_string(removed.size()),
                         [&] { store_.delete_assets(removed); });
    }
    if (!removed.empty())
        Log("info", "assets_collected")
            .kv("count", removed.size())
            .kv("bytes_freed", freed)
            .kv("grace_seconds", grace);
}

std::set<std::string> JobManager::assets_in_use(const std::string& except_job) const {
    std::set<std::string> used;
    for (const auto& [id, job] : jobs_)
        if (id != except_job)
            for (const v1::BundleFile& f : job->request.bundle().files()) used.insert(f.sha256());
    for (const auto& [sha, n] : submitting_assets_) used.insert(sha);
    return used;
}

}  // namespace render::server
