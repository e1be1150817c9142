#pragma once

// When a job FAILS instead of being handed out again (docs/guide/service.md, "Workers";
// docs/guide/reliability.md): a poison job, whose leases fail or whose workers die on it, and a job
// no live worker has the memory for. The bookkeeping of one job, kept in memory only: a
// restarted server counts afresh. Not thread-safe (the job manager calls it under its lock).

#include <cstdint>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "server/scheduler.h"

namespace render::server {

// A job whose leases failed on this many distinct workers that reported an error (or on every
// worker the server knows, if fewer) is a poison job: it FAILS with the last error instead of
// being handed out for ever (the same error from two workers).
inline constexpr size_t kMaxReportingWorkers = 2;
// Counting workers that lost a lease of the job (died or stopped heartbeating) as well, this
// many distinct ones fail it: a loss may be a machine taken away, so one more is asked for.
inline constexpr size_t kMaxFailedWorkers = 3;
// Workers lost after they reported rendering progress on the lease count only toward this
// larger limit: under a chaos soak (a worker SIGKILLed every 2 s among 3) healthy jobs failed
// after 3 such losses; a scene that crashes its workers mid-render still fails, later.
inline constexpr size_t kMaxLostRenderingWorkers = 10;

// A live worker as the memory rule sees it: its memory limit, 0 while unknown (known from its
// latest refusal for memory).
struct WorkerMemory {
    std::string id;
    uint64_t memory_limit = 0;
};

class JobFailures {
  public:
    // --- the poison rule ---
    // A worker reported the lease as failed with `error`. An undelivered report is a transport
    // fault after a render that worked: counted like a lease lost while rendering, so one
    // worker's unlucky link does not fail the job, while a job whose reports no server
    // accepts still fails at the larger limit.
    void lease_failed(const std::string& worker_id, const std::string& lease_id,
                      const std::string& error, bool report_undelivered);
    // The lease expired: its worker died or hung on it. A lease that had rendered iterations
    // counts toward the larger limit (the worker was likely killed from outside).
    void lease_lost(const std::string& worker_id, const std::string& lease_id);
    // The lease's report stream went idle mid-report: a loss while rendering.
    void report_stream_idle(const std::string& worker_id, const std::string& lease_id);
    // The worker measured rendering progress on the lease (a heartbeat with rates).
    void lease_progressed(const std::string& lease_id) { progressed_leases_.insert(lease_id); }
    // A report of the job merged: it renders somewhere, so earlier failures were not the
    // scene's fault (a poison job never merges anything) and no longer count.
    void report_merged(const std::string& lease_id);
    // Why the job fails now under the limits above, or nullopt. `known_workers`: how many
    // workers the server knows (reported failures on all of them suffice, up to the limit).
    std::optional<std::string> poison_verdict(size_t known_workers) const;

    // --- the memory wait ---
    // A worker refused a lease for memory (`limit` its own, `needed` the estimate): not a
    // failure, the job waits for a worker with more memory.
    void refused_for_memory(const std::string& worker_id, uint64_t limit, uint64_t needed,
                            const std::string& error);
    bool refused_for_memory() const { return !memory_refusals_.empty(); }
    // The largest estimate a refusal reported.
    uint64_t memory_needed() const { return memory_needed_; }
    // The worker cannot take the job: it refused it, or its limit (`worker_limit`, 0 when
    // unknown) is below what the job needs.
    bool lacks_memory(const std::string& worker_id, uint64_t worker_limit) const;
    // The job was refused for memory and none of the `live` workers can take it; false
    // without live workers.
    bool memory_blocked(const std::vector<WorkerMemory>& live) const;
    // Job.waiting for a memory-blocked job; `wait_seconds` is server --memory-wait.
    std::string memory_waiting(double wait_seconds) const;
    // Called at every tick with whether the job is memory-blocked now: why it fails once it
    // has been blocked for `wait_seconds` without a break, else nullopt.
    std::optional<std::string> memory_wait_verdict(bool blocked, TimePoint now,
                                                   double wait_seconds);

  private:
    // Workers that reported a lease as failed since the last merged report, those whose lease
    // expired in that time, and the last error.
    std::set<std::string> failed_workers_;
    std::set<std::string> lost_workers_;
    std::string last_failure_;
    // Leases whose worker reported rendering progress, and the workers that lost such a lease.
    std::set<std::string> progressed_leases_;
    std::set<std::string> lost_rendering_workers_;
    // Workers that refused the job for memory, with their limits; the largest estimate, and
    // the last refusal's message; since when no live worker could take it.
    std::map<std::string, uint64_t> memory_refusals_;
    uint64_t memory_needed_ = 0;
    std::string memory_error_;
    std::optional<TimePoint> memory_blocked_since_;
};

}  // namespace render::server
