#pragma once

// The lease table and the iteration bookkeeping of every frame: which ranges are merged, which
// are leased (and until when), which are waiting to be handed out again. Not thread-safe: the
// owner (JobManager) serializes calls. Time comes from an injectable clock so that tests can
// expire leases without sleeping.

#include <chrono>
#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "server/interval_set.h"

namespace render::server {

using SteadyClock = std::chrono::steady_clock;
using TimePoint = SteadyClock::time_point;

// Mirrors render.v1.JobState.
enum class JobState { Queued = 1, Running = 2, Done = 3, Cancelled = 4, Failed = 5 };
bool is_terminal(JobState s);

struct FramePlan {
    uint64_t target = 0;         // iterations; 0 = time budget only
    double budget_seconds = 0;   // 0 = none
    double elapsed_seconds = 0;  // render time spent in earlier runs of the server
    IntervalSet merged;          // ranges already merged (from a checkpoint)
    bool done = false;
    // Adaptive sampling (docs/reference/adaptive-sampling.md): no iteration at or past this is
    // handed out (the end of the current round) until open_round moves it; 0 = no limit.
    uint64_t round_end = 0;
};

struct LeaseGrant {
    std::string lease_id;
    std::string worker_id;
    std::string job_id;
    uint32_t frame = 0;
    Range range;
};

struct FrameProgress {
    uint64_t merged = 0;
    uint64_t target = 0;
    double elapsed_seconds = 0;
    bool done = false;
};

// Monotonic counts of lease events since the server started (for /metrics).
struct LeaseCounters {
    uint64_t granted = 0;
    uint64_t expired = 0;   // not heartbeaten in time: the range went back to the queue
    uint64_t released = 0;  // given up by a worker that could not render it: queued again
};

enum class MergeDecision { Accept, UnknownLease, AlreadyMerged, Reissued, JobInactive };
const char* to_string(MergeDecision d);

// How long a lease takes at the worker's measured rate, i.e. how far apart one worker's
// reports are. Every report costs the server a merge of the frame's whole sums (and the worker
// a transfer of them), whatever the lease's length, so leases are sized to be long enough for
// that cost to be small, and short enough for previews, error estimates and the work lost with
// a dead worker to stay bounded:
//   * at least target_lease_seconds, and at least the job's measured per-report merge cost
//     divided by max_report_cost_fraction (a large frame merges slowly: its leases grow);
//   * at most max_lease_seconds, unless one iteration alone takes longer: a lease is never
//     less than one iteration (an iteration cannot be split), and a long iteration's lease
//     stays alive through the worker's heartbeats.
struct SchedulerOptions {
    double lease_timeout_seconds = 30;
    double target_lease_seconds = 3;
    double max_lease_seconds = 30;
    double max_report_cost_fraction = 0.01;
};

class Scheduler {
  public:
    using ClockFn = std::function<TimePoint()>;
    explicit Scheduler(SchedulerOptions options, ClockFn clock = SteadyClock::now);

    // Adds a job (new or restored). Restored frames may carry merged ranges: everything below
    // the highest merged iteration that is not merged is queued again.
    void add_job(const std::string& job_id, int priority, uint64_t sequence, JobState state,
                 std::vector<FramePlan> frames);
    bool has_job(const std::string& job_id) const { return jobs_.count(job_id) > 0; }
    JobState state(const std::string& job_id) const;
    // Changes a job's priority (higher is leased first); false for an unknown job.
    bool set_priority(const std::string& job_id, int priority);
    // Forgets a job in a terminal state (its leases are void already); false otherwise.
    bool remove_job(const std::string& job_id);
    // Sets a job's state; a terminal state voids its leases (heartbeats report them cancelled).
    void set_state(const std::string& job_id, JobState state);

    // The server's cost of merging one report of the job (seconds, measured), which sizes the
    // job's leases (SchedulerOptions). A running average over the job's reports.
    void note_report_cost(const std::string& job_id, double seconds);
    // The number of iterations of this job the worker gets in its next lease (before the
    // frame's target and time budget cap it): 1 until the worker's rate for the job is known.
    uint64_t lease_size(const std::string& worker_id, const std::string& job_id) const;

    // The next range for this worker, or nothing when no job needs iterations now. Jobs for
    // which `skip(job_id)` is true are passed over (a job this worker refused for memory).
    std::optional<LeaseGrant> lease(const std::string& worker_id,
                                    const std::function<bool(const std::string&)>& skip = {});

    // Extends the worker's leases; returns those of `lease_ids` the worker must stop.
    std::vector<std::string> heartbeat(const std::string& worker_id,
                                       const std::vector<std::string>& lease_ids);

    // The worker gave lease `lease_id` up (it could not render it): its range goes back to be
    // handed out again, as on expiry. Returns the grant, or nothing when the lease is not an
    // active lease of `worker_id`.
    std::optional<LeaseGrant> release(const std::string& worker_id, const std::string& lease_id);

    // Looks up an active (or expired but not yet reissued) lease without changing anything.
    std::optional<LeaseGrant> find_lease(const std::string& lease_id) const;

    // Decides whether the report of `lease_id` is merged. On Accept the range is recorded as
    // being merged at once (so that a duplicate arriving meanwhile is dropped) and `grant` is
    // filled; the caller adds the sums and then calls end_merge. `render_seconds` feeds the
    // worker's measured rate for range sizing.
    MergeDecision begin_merge(const std::string& lease_id, double render_seconds,
                              LeaseGrant* grant);
    // The range of an accepted report is now in the frame's sums.
    void end_merge(const LeaseGrant& grant);

    // Expires leases and closes time budgets; returns frames that just became complete, each
    // once (also reported by complete_frames_after_merge).
    std::vector<std::pair<std::string, uint32_t>> tick();
    // The leases expired since the last call (each once), for counting lost workers per job.
    std::vector<LeaseGrant> take_expired();
    // No iterations past those handed out: the frame completes once they are merged (as when
    // its time budget runs out). For a target error reached.
    void close_frame(const std::string& job_id, uint32_t frame);
    // Adaptive frames whose current round is wholly merged (every iteration before
    // plan.round_end), not closed and below their target: the next round's mask is due. Each
    // such frame at every call, until open_round or close_frame.
    std::vector<std::pair<std::string, uint32_t>> round_boundaries() const;
    // The next round's iterations may be handed out: those before `round_end`.
    void open_round(const std::string& job_id, uint32_t frame, uint64_t round_end);
    // Marks a frame finished (after its EXR is written); returns true when the whole job is.
    bool finish_frame(const std::string& job_id, uint32_t frame);

    FrameProgress progress(const std::string& job_id, uint32_t frame) const;
    std::vector<Range> merged_ranges(const std::string& job_id, uint32_t frame) const;
    // Lease ids currently held by a worker.
    std::vector<std::string> worker_leases(const std::string& worker_id) const;
    size_t active_lease_count() const { return leases_.size(); }
    // Whether any worker holds a lease of the job now.
    bool job_has_lease(const std::string& job_id) const;
    const LeaseCounters& lease_counters() const { return counters_; }
    // Iterations of unfinished jobs not handed out yet: ranges waiting to be leased again plus
    // those below the iteration target never leased (a pure time budget counts its pending
    // ranges only).
    uint64_t queued_iterations() const;

  private:
    struct Frame {
        FramePlan plan;
        uint64_t frontier = 1;  // the first iteration never handed out
        IntervalSet pending;    // handed out, expired, to be handed out again
        IntervalSet leased;
        IntervalSet merging;               // accepted, being added to the sums
        std::optional<TimePoint> started;  // first lease in this run
        bool closed = false;               // time budget used: no iterations past frontier
        bool complete_reported = false;
    };
    struct Job {
        std::string id;
        int priority = 0;
        uint64_t sequence = 0;
        JobState state = JobState::Queued;
        std::vector<Frame> frames;
        double report_cost_seconds = 0;  // running average; 0 until a report is measured
    };
    struct Lease {
        LeaseGrant grant;
        TimePoint expires;
    };

    double elapsed(const Frame& f, TimePoint now) const;
    void expire(TimePoint now);
    void close_budgets(TimePoint now);
    bool is_complete(const Frame& f) const;
    std::vector<Job*> ordered_jobs();
    std::string new_lease_id();

    SchedulerOptions options_;
    ClockFn clock_;
    std::map<std::string, Job> jobs_;
    std::map<std::string, Lease> leases_;
    std::map<std::string, LeaseGrant> expired_;  // expired, range maybe not yet reissued
    std::vector<LeaseGrant> newly_expired_;      // expired since the last take_expired()
    std::map<std::pair<std::string, std::string>, double> rates_;  // (worker, job) -> it/s
    std::string lease_prefix_;
    uint64_t lease_counter_ = 0;
    LeaseCounters counters_;
};

}  // namespace render::server
