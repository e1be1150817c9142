#include "server/scheduler.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>

namespace render::server {

bool is_terminal(JobState s) {
    return s == JobState::Done || s == JobState::Cancelled || s == JobState::Failed;
}

const char* to_string(MergeDecision d) {
    switch (d) {
        case MergeDecision::Accept:
            return "accept";
        case MergeDecision::UnknownLease:
            return "unknown_lease";
        case MergeDecision::AlreadyMerged:
            return "already_merged";
        case MergeDecision::Reissued:
            return "expired_and_reissued";
        case MergeDecision::JobInactive:
            return "job_inactive";
    }
    return "?";
}

namespace {
constexpr uint64_t kMaxLeaseIterations = 1000000;
constexpr size_t kMaxExpiredKept = 100000;
}  // namespace

Scheduler::Scheduler(SchedulerOptions options, ClockFn clock)
    : options_(options), clock_(std::move(clock)) {
    std::random_device rd;
    char buf[32];
    std::snprintf(buf, sizeof buf, "L%08x", unsigned(rd()));
    lease_prefix_ = buf;
}

void Scheduler::add_job(const std::string& job_id, int priority, uint64_t sequence, JobState state,
                        std::vector<FramePlan> frames) {
    Job job;
    job.id = job_id;
    job.priority = priority;
    job.sequence = sequence;
    job.state = state;
    for (FramePlan& plan : frames) {
        Frame f;
        f.plan = std::move(plan);
        f.frontier = f.plan.merged.max_end(1);
        if (f.frontier > 1) {
            f.pending.add({1, f.frontier});
            for (const Range& r : f.plan.merged.ranges()) f.pending.subtract(r);
        }
        job.frames.push_back(std::move(f));
    }
    jobs_[job_id] = std::move(job);
}

JobState Scheduler::state(const std::string& job_id) const {
    auto it = jobs_.find(job_id);
    return it == jobs_.end() ? JobState::Failed : it->second.state;
}

bool Scheduler::set_priority(const std::string& job_id, int priority) {
    auto it = jobs_.find(job_id);
    if (it == jobs_.end()) return false;
    it->second.priority = priority;
    return true;
}

bool Scheduler::remove_job(const std::string& job_id) {
    auto it = jobs_.find(job_id);
    if (it == jobs_.end() || !is_terminal(it->second.state)) return false;
    for (auto r = rates_.begin(); r != rates_.end();)
        r = r->first.second == job_id ? rates_.erase(r) : std::next(r);
    jobs_.erase(it);
    return true;
}

void Scheduler::set_state(const std::string& job_id, JobState state) {
    auto it = jobs_.find(job_id);
    if (it == jobs_.end()) return;
    it->second.state = state;
    if (!is_terminal(state)) return;
    for (auto l = leases_.begin(); l != leases_.end();) {
        if (l->second.grant.job_id == job_id)
            l = leases_.erase(l);
        else
            ++l;
    }
    for (auto l = expired_.begin(); l != expired_.end();) {
        if (l->second.job_id == job_id)
            l = expired_.erase(l);
        else
            ++l;
    }
    for (Frame& f : it->second.frames) f.leased.clear();
}

double Scheduler::elapsed(const Frame& f, TimePoint now) const {
    double e = f.plan.elapsed_seconds;
    if (f.started) e += std::chrono::duration<double>(now - *f.started).count();
    return e;
}

void Scheduler::expire(TimePoint now) {
    for (auto l = leases_.begin(); l != leases_.end();) {
        if (l->second.expires < now) {
            const LeaseGrant& g = l->second.grant;
            auto job = jobs_.find(g.job_id);
            if (job != jobs_.end() && g.frame < job->second.frames.size()) {
                Frame& f = job->second.frames[g.frame];
                f.leased.subtract(g.range);
                f.pending.add(g.range);
            }
            expired_[l->first] = g;
            newly_expired_.push_back(g);
            ++counters_.expired;
            l = leases_.erase(l);
        } else {
            ++l;
        }
    }
    while (expired_.size() > kMaxExpiredKept) expired_.erase(expired_.begin());
}

std::optional<LeaseGrant> Scheduler::release(const std::string& worker_id,
                                             const std::string& lease_id) {
    auto l = leases_.find(lease_id);
    if (l == leases_.end() || l->second.grant.worker_id != worker_id) return std::nullopt;
    const LeaseGrant g = l->second.grant;
    auto job = jobs_.find(g.job_id);
    if (job != jobs_.end() && g.frame < job->second.frames.size()) {
        Frame& f = job->second.frames[g.frame];
        f.leased.subtract(g.range);
        f.pending.add(g.range);
    }
    leases_.erase(l);
    ++counters_.released;
    return g;
}

uint64_t Scheduler::queued_iterations() const {
    uint64_t n = 0;
    for (const auto& [id, job] : jobs_) {
        if (is_terminal(job.state)) continue;
        for (const Frame& f : job.frames) {
            if (f.plan.done || f.complete_reported) continue;
            n += f.pending.total();
            if (!f.closed && f.plan.target > 0 && f.frontier <= f.plan.target)
                n += f.plan.target + 1 - f.frontier;
        }
    }
    return n;
}

void Scheduler::close_budgets(TimePoint now) {
    for (auto& [id, job] : jobs_) {
        if (is_terminal(job.state)) continue;
        for (Frame& f : job.frames)
            if (!f.closed && !f.plan.done && f.plan.budget_seconds > 0 &&
                elapsed(f, now) >= f.plan.budget_seconds)
                f.closed = true;
    }
}

bool Scheduler::is_complete(const Frame& f) const {
    if (f.plan.done || !f.pending.empty() || !f.leased.empty() || !f.merging.empty()) return false;
    uint64_t end = 0;
    if (f.closed)
        end = f.frontier;
    else if (f.plan.target > 0)
        end = f.plan.target + 1;
    if (end <= 1) return false;
    return f.plan.merged.contains({1, end});
}

void Scheduler::note_report_cost(const std::string& job_id, double seconds) {
    auto it = jobs_.find(job_id);
    if (it == jobs_.end() || !(seconds >= 0) || !std::isfinite(seconds)) return;
    double& cost = it->second.report_cost_seconds;
    cost = cost == 0 ? seconds : 0.5 * cost + 0.5 * seconds;
}

uint64_t Scheduler::lease_size(const std::string& worker_id, const std::string& job_id) const {
    auto it = rates_.find({worker_id, job_id});
    if (it == rates_.end() || !(it->second > 0) || !std::isfinite(it->second)) return 1;
    const double rate = it->second;  // iterations per second
    double shortest = options_.target_lease_seconds;
    if (auto job = jobs_.find(job_id); job != jobs_.end() && options_.max_report_cost_fraction > 0)
        shortest =
            std::max(shortest, job->second.report_cost_seconds / options_.max_report_cost_fraction);
    shortest = std::min(shortest, options_.max_lease_seconds);
    // The fewest iterations that last `shortest` (a tolerance keeps an exact product, 10 it/s
    // for 3 s, from rounding up to one more), but no more than fit in max_lease_seconds.
    const double want = std::ceil(rate * shortest - 1e-9);
    const double most = std::floor(rate * options_.max_lease_seconds + 1e-9);
    const double n = std::min(want, most);
    if (!(n >= 1)) return 1;
    return std::min<uint64_t>(uint64_t(std::min(n, double(kMaxLeaseIterations))),
                              kMaxLeaseIterations);
}

std::vector<Scheduler::Job*> Scheduler::ordered_jobs() {
    std::vector<Job*> out;
    for (auto& [id, job] : jobs_)
        if (!is_terminal(job.state)) out.push_back(&job);
    std::sort(out.begin(), out.end(), [](const Job* a, const Job* b) {
        if (a->priority != b->priority) return a->priority > b->priority;
        return a->sequence < b->sequence;
    });
    return out;
}

std::string Scheduler::new_lease_id() {
    char buf[32];
    std::snprintf(buf, sizeof buf, "-%010llu", (unsigned long long)++lease_counter_);
    return lease_prefix_ + buf;
}

std::optional<LeaseGrant> Scheduler::lease(const std::string& worker_id,
                                           const std::function<bool(const std::string&)>& skip) {
    TimePoint now = clock_();
    expire(now);
    close_budgets(now);
    for (Job* job : ordered_jobs()) {
        if (skip && skip(job->id)) continue;
        uint64_t size = lease_size(worker_id, job->id);
        for (uint32_t index = 0; index < job->frames.size(); ++index) {
            Frame& f = job->frames[index];
            if (f.plan.done || f.complete_reported) continue;
            Range r;
            if (auto p = f.pending.first()) {
                r = {p->first, std::min(p->end, p->first + size)};
                f.pending.subtract(r);
            } else if (!f.closed && (f.plan.target == 0 || f.frontier <= f.plan.target) &&
                       (f.plan.round_end == 0 || f.frontier < f.plan.round_end)) {
                uint64_t n = size;
                if (f.plan.target > 0) n = std::min(n, f.plan.target + 1 - f.frontier);
                // A lease lies within the current round: its mask is the only one known.
                if (f.plan.round_end > 0) n = std::min(n, f.plan.round_end - f.frontier);
                if (f.plan.budget_seconds > 0) {
                    auto rate = rates_.find({worker_id, job->id});
                    if (rate != rates_.end()) {
                        double left = f.plan.budget_seconds - elapsed(f, now);
                        double cap = std::floor(rate->second * std::max(left, 0.0)) + 1;
                        n = std::min<uint64_t>(n, uint64_t(std::max(cap, 1.0)));
                    }
                }
                r = {f.frontier, f.frontier + n};
                f.frontier = r.end;
            } else {
                continue;
            }
            f.leased.add(r);
            if (!f.started) f.started = now;
            if (job->state == JobState::Queued) job->state = JobState::Running;
            LeaseGrant g{new_lease_id(), worker_id, job->id, index, r};
            ++counters_.granted;
            leases_[g.lease_id] =
                Lease{g, now + std::chrono::duration_cast<SteadyClock::duration>(
                                   std::chrono::duration<double>(options_.lease_timeout_seconds))};
            return g;
        }
    }
    return std::nullopt;
}

std::vector<std::string> Scheduler::heartbeat(const std::string& worker_id,
                                              const std::vector<std::string>& lease_ids) {
    TimePoint now = clock_();
    expire(now);
    auto deadline = now + std::chrono::duration_cast<SteadyClock::duration>(
                              std::chrono::duration<double>(options_.lease_timeout_seconds));
    for (auto& [id, lease] : leases_)
        if (lease.grant.worker_id == worker_id) lease.expires = deadline;
    std::vector<std::string> cancelled;
    for (const std::string& id : lease_ids) {
        auto it = leases_.find(id);
        if (it == leases_.end() || it->second.grant.worker_id != worker_id) {
            // Unknown or expired: unless its range still waits unclaimed, the work is lost.
            auto e = expired_.find(id);
            bool salvageable = false;
            if (e != expired_.end()) {
                auto job = jobs_.find(e->second.job_id);
                salvageable = job != jobs_.end() && !is_terminal(job->second.state) &&
                              job->second.frames[e->second.frame].pending.contains(e->second.range);
            }
            if (!salvageable) cancelled.push_back(id);
        }
    }
    return cancelled;
}

std::optional<LeaseGrant> Scheduler::find_lease(const std::string& lease_id) const {
    if (auto it = leases_.find(lease_id); it != leases_.end()) return it->second.grant;
    if (auto it = expired_.find(lease_id); it != expired_.end()) return it->second;
    return std::nullopt;
}

MergeDecision Scheduler::begin_merge(const std::string& lease_id, double render_seconds,
                                     LeaseGrant* grant) {
    TimePoint now = clock_();
    expire(now);
    LeaseGrant g;
    bool was_active = false;
    if (auto it = leases_.find(lease_id); it != leases_.end()) {
        g = it->second.grant;
        leases_.erase(it);
        was_active = true;
    } else if (auto e = expired_.find(lease_id); e != expired_.end()) {
        g = e->second;
        expired_.erase(e);
    } else {
        return MergeDecision::UnknownLease;
    }
    auto job = jobs_.find(g.job_id);
    if (job == jobs_.end() || g.frame >= job->second.frames.size())
        return MergeDecision::UnknownLease;
    Frame& f = job->second.frames[g.frame];
    if (was_active) f.leased.subtract(g.range);
    if (is_terminal(job->second.state)) return MergeDecision::JobInactive;
    if (f.plan.merged.overlaps(g.range) || f.merging.overlaps(g.range))
        return MergeDecision::AlreadyMerged;
    if (!was_active) {
        if (!f.pending.contains(g.range)) return MergeDecision::Reissued;
        f.pending.subtract(g.range);
    }
    f.merging.add(g.range);
    if (render_seconds > 0) {
        double rate = double(g.range.size()) / render_seconds;
        auto key = std::make_pair(g.worker_id, g.job_id);
        auto r = rates_.find(key);
        rates_[key] = r == rates_.end() ? rate : 0.5 * r->second + 0.5 * rate;
    }
    if (grant) *grant = g;
    return MergeDecision::Accept;
}

void Scheduler::end_merge(const LeaseGrant& grant) {
    auto job = jobs_.find(grant.job_id);
    if (job == jobs_.end() || grant.frame >= job->second.frames.size()) return;
    Frame& f = job->second.frames[grant.frame];
    f.merging.subtract(grant.range);
    f.plan.merged.add(grant.range);
}

std::vector<LeaseGrant> Scheduler::take_expired() {
    std::vector<LeaseGrant> out;
    out.swap(newly_expired_);
    return out;
}

std::vector<std::pair<std::string, uint32_t>> Scheduler::tick() {
    TimePoint now = clock_();
    expire(now);
    close_budgets(now);
    std::vector<std::pair<std::string, uint32_t>> complete;
    for (auto& [id, job] : jobs_) {
        if (is_terminal(job.state)) continue;
        for (uint32_t i = 0; i < job.frames.size(); ++i) {
            Frame& f = job.frames[i];
            if (f.complete_reported || !is_complete(f)) continue;
            f.complete_reported = true;
            f.plan.elapsed_seconds = elapsed(f, now);
            f.started.reset();
            complete.emplace_back(id, i);
        }
    }
    return complete;
}

void Scheduler::close_frame(const std::string& job_id, uint32_t frame) {
    auto it = jobs_.find(job_id);
    if (it == jobs_.end() || frame >= it->second.frames.size()) return;
    it->second.frames[frame].closed = true;
}

std::vector<std::pair<std::string, uint32_t>> Scheduler::round_boundaries() const {
    std::vector<std::pair<std::string, uint32_t>> out;
    for (const auto& [id, job] : jobs_) {
        if (is_terminal(job.state)) continue;
        for (uint32_t i = 0; i < job.frames.size(); ++i) {
            const Frame& f = job.frames[i];
            const uint64_t end = f.plan.round_end;
            if (end == 0 || f.closed || f.plan.done || f.complete_reported || f.frontier != end ||
                (f.plan.target > 0 && end > f.plan.target) || !f.pending.empty() ||
                !f.leased.empty() || !f.merging.empty() || !f.plan.merged.contains({1, end}))
                continue;
            out.emplace_back(id, i);
        }
    }
    return out;
}

void Scheduler::open_round(const std::string& job_id, uint32_t frame, uint64_t round_end) {
    auto it = jobs_.find(job_id);
    if (it == jobs_.end() || frame >= it->second.frames.size()) return;
    Frame& f = it->second.frames[frame];
    if (round_end > f.plan.round_end) f.plan.round_end = round_end;
}

bool Scheduler::finish_frame(const std::string& job_id, uint32_t frame) {
    auto it = jobs_.find(job_id);
    if (it == jobs_.end() || frame >= it->second.frames.size()) return false;
    Frame& f = it->second.frames[frame];
    if (f.started) {
        f.plan.elapsed_seconds = elapsed(f, clock_());
        f.started.reset();
    }
    f.plan.done = true;
    for (const Frame& other : it->second.frames)
        if (!other.plan.done) return false;
    it->second.state = JobState::Done;
    return true;
}

FrameProgress Scheduler::progress(const std::string& job_id, uint32_t frame) const {
    FrameProgress p;
    auto it = jobs_.find(job_id);
    if (it == jobs_.end() || frame >= it->second.frames.size()) return p;
    const Frame& f = it->second.frames[frame];
    p.merged = f.plan.merged.total();
    p.target = f.plan.target;
    p.elapsed_seconds = elapsed(f, clock_());
    p.done = f.plan.done;
    return p;
}

std::vector<Range> Scheduler::merged_ranges(const std::string& job_id, uint32_t frame) const {
    auto it = jobs_.find(job_id);
    if (it == jobs_.end() || frame >= it->second.frames.size()) return {};
    return it->second.frames[frame].plan.merged.ranges();
}

std::vector<std::string> Scheduler::worker_leases(const std::string& worker_id) const {
    std::vector<std::string> out;
    for (const auto& [id, lease] : leases_)
        if (lease.grant.worker_id == worker_id) out.push_back(id);
    return out;
}

bool Scheduler::job_has_lease(const std::string& job_id) const {
    for (const auto& [id, lease] : leases_)
        if (lease.grant.job_id == job_id) return true;
    return false;
}

}  // namespace render::server
