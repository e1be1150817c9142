#include "server/failure_policy.h"

#include <algorithm>
#include <chrono>
#include <cstdio>

#include "core/base/memory_budget.h"

namespace render::server {

void JobFailures::lease_failed(const std::string& worker_id, const std::string& lease_id,
                               const std::string& error, bool report_undelivered) {
    progressed_leases_.erase(lease_id);
    if (report_undelivered)
        lost_rendering_workers_.insert(worker_id);
    else
        failed_workers_.insert(worker_id);
    last_failure_ = error;
}

void JobFailures::lease_lost(const std::string& worker_id, const std::string& lease_id) {
    if (progressed_leases_.erase(lease_id))
        lost_rendering_workers_.insert(worker_id);
    else
        lost_workers_.insert(worker_id);
}

void JobFailures::report_stream_idle(const std::string& worker_id, const std::string& lease_id) {
    progressed_leases_.erase(lease_id);
    lost_rendering_workers_.insert(worker_id);
}

void JobFailures::report_merged(const std::string& lease_id) {
    failed_workers_.clear();
    lost_workers_.clear();
    lost_rendering_workers_.clear();
    progressed_leases_.erase(lease_id);
}

std::optional<std::string> JobFailures::poison_verdict(size_t known_workers) const {
    std::set<std::string> either = failed_workers_;
    either.insert(lost_workers_.begin(), lost_workers_.end());
    // Reported failures: on every known worker (up to the limit) is enough; with lost leases
    // the limit itself is needed.
    const size_t needed_reported = std::clamp<size_t>(known_workers, 1, kMaxReportingWorkers);
    std::set<std::string> any = either;
    any.insert(lost_rendering_workers_.begin(), lost_rendering_workers_.end());
    if (failed_workers_.size() < needed_reported && either.size() < kMaxFailedWorkers &&
        any.size() < kMaxLostRenderingWorkers)
        return std::nullopt;
    const size_t lost = lost_workers_.size() + lost_rendering_workers_.size();
    std::string why =
        "failed on " + std::to_string(any.size()) + " worker" + (any.size() == 1 ? "" : "s");
    if (lost > 0)
        why += " (" + std::to_string(lost) +
               " lost the lease: died or stopped heartbeating while rendering it)";
    why += last_failure_.empty() ? std::string("; no worker reported an error")
                                 : "; last error: " + last_failure_;
    return why;
}

void JobFailures::refused_for_memory(const std::string& worker_id, uint64_t limit, uint64_t needed,
                                     const std::string& error) {
    memory_refusals_[worker_id] = limit;
    memory_needed_ = std::max(memory_needed_, needed);
    memory_error_ = error;
}

bool JobFailures::lacks_memory(const std::string& worker_id, uint64_t worker_limit) const {
    if (memory_refusals_.count(worker_id)) return true;
    return memory_needed_ > 0 && worker_limit > 0 && worker_limit < memory_needed_;
}

bool JobFailures::memory_blocked(const std::vector<WorkerMemory>& live) const {
    if (memory_refusals_.empty() || live.empty()) return false;
    for (const WorkerMemory& w : live)
        if (!lacks_memory(w.id, w.memory_limit)) return false;
    return true;
}

namespace {

// The wait as the server's flag was given ("%g": 300, 0.5).
std::string wait_text(double wait_seconds) {
    char wait[32];
    std::snprintf(wait, sizeof wait, "%g", wait_seconds);
    return wait;
}

}  // namespace

std::string JobFailures::memory_waiting(double wait_seconds) const {
    uint64_t largest_limit = 0;
    for (const auto& [id, limit] : memory_refusals_) largest_limit = std::max(largest_limit, limit);
    const size_t n = memory_refusals_.size();
    return "waiting for a worker with more than " + format_bytes(largest_limit) +
           " of memory: the job needs at least " + format_bytes(memory_needed_) +
           " (refused for memory by " + std::to_string(n) + " worker" + (n == 1 ? "" : "s") +
           "; it fails if none joins within " + wait_text(wait_seconds) +
           " s, server --memory-wait)";
}

std::optional<std::string> JobFailures::memory_wait_verdict(bool blocked, TimePoint now,
                                                            double wait_seconds) {
    if (!blocked) {
        memory_blocked_since_.reset();
        return std::nullopt;
    }
    if (!memory_blocked_since_) memory_blocked_since_ = now;
    const double waited = std::chrono::duration<double>(now - *memory_blocked_since_).count();
    if (waited < wait_seconds) return std::nullopt;
    const size_t n = memory_refusals_.size();
    return "no worker has the memory for this job: refused for memory by " + std::to_string(n) +
           " worker" + (n == 1 ? "" : "s") + " and no live worker with more joined within " +
           wait_text(wait_seconds) + " s (server --memory-wait); last refusal: " + memory_error_;
}

}  // namespace render::server
