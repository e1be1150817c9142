// The job manager's merging of reports: a report's header checked against its lease, its
// values added exactly once to the frame's sums, one report of a job at a time.

#include "server/job_manager.h"

#include <chrono>
#include <cmath>

#include "core/render/job_limits.h"
#include "core/util/log.h"
#include "server/job_manager_detail.h"

namespace render::server {

using grpc::Status;
using namespace detail;

Status JobManager::check_report(const v1::ReportHeader& header, size_t* values, size_t* layers,
                                size_t* exact_words, bool* drop) {
    *drop = false;
    *exact_words = 0;
    std::lock_guard lock(mu_);
    std::optional<LeaseGrant> grant = scheduler_.find_lease(header.lease_id());
    if (!grant) {
        *drop = true;
        return Status::OK;
    }
    auto job = find(grant->job_id);
    if (!job) {
        *drop = true;
        return Status::OK;
    }
    if (header.width() != uint32_t(job->row.width) || header.height() != uint32_t(job->row.height))
        return invalid("report size " + std::to_string(header.width()) + "x" +
                       std::to_string(header.height()) + " differs from the job's film " +
                       std::to_string(job->row.width) + "x" + std::to_string(job->row.height));
    uint64_t count = grant->range.size();
    uint64_t odd = grant->range.end / 2 - grant->range.first / 2;
    if (header.count() != count)
        return invalid("report count " + std::to_string(header.count()) + " differs from the " +
                       "lease's range size " + std::to_string(count));
    if (header.odd_count() != odd)
        return invalid("report odd_count " + std::to_string(header.odd_count()) +
                       " differs from the lease's " + std::to_string(odd));
    if (header.odd_sum_omitted() && count != 1)
        return invalid("report omits odd_sum but sums " + std::to_string(count) +
                       " iterations (only a one-iteration report may)");
    if (!std::isfinite(header.render_seconds()) || header.render_seconds() < 0)
        return invalid("report render_seconds must be finite and >= 0");
    *values = size_t(job->row.width) * size_t(job->row.height) * 3;
    *layers = TechniqueLayers::names(job->settings.layers).size();
    if (header.layer_count() != *layers)
        return invalid("report has " + std::to_string(header.layer_count()) +
                       " technique layers, the job's layers option gives " +
                       std::to_string(*layers));
    const bool adaptive = job->settings.adaptive > 0;
    if (header.exact_sums() != adaptive)
        return invalid(adaptive ? "report of an adaptive job without its exact sums"
                                : "report has exact sums, but the job is not adaptive");
    if (adaptive)
        *exact_words =
            size_t(job->row.width) * size_t(job->row.height) * (header.odd_sum_omitted() ? 1 : 2);
    return Status::OK;
}

Status JobManager::report(const v1::ReportHeader& header, ReportValues&& values, bool* merged) {
    *merged = false;
    LeaseGrant grant;
    std::shared_ptr<JobData> job;
    MergeDecision decision;
    int64_t epoch = 0;  // the hold the lease was granted in (shared store)
    {
        std::lock_guard lock(mu_);
        decision = scheduler_.begin_merge(header.lease_id(), header.render_seconds(), &grant);
        if (decision == MergeDecision::Accept) job = find(grant.job_id);
        if (job) epoch = holds(*job) ? job->hold_epoch : -2;
    }
    {
        // Deleted in a batch by tick(), not here: this runs in the job's report slot.
        std::lock_guard lock(reported_mu_);
        reported_leases_.push_back(header.lease_id());
    }
    if (decision != MergeDecision::Accept || !job) {
        metrics_.report_dropped(decision == MergeDecision::Accept ? "job_inactive"
                                                                  : to_string(decision));
        Log("warn", "report_dropped")
            .kv("lease", header.lease_id())
            .kv("reason", to_string(decision));
        return Status::OK;
    }
    FrameData& frame = *job->frames[grant.frame];
    double elapsed = 0;
    {
        std::lock_guard lock(mu_);
        elapsed = scheduler_.progress(grant.job_id, grant.frame).elapsed_seconds;
    }
    using clock = std::chrono::steady_clock;
    clock::duration add_time{}, checkpoint_time{};
    uint64_t merged_count = 0;
    double merged_error = 1;
    bool hold_lost = false;
    // A checkpoint by every report: on a shared store only within a hold just renewed.
    const bool checkpoint_now = options_.checkpoint_seconds <= 0 && still_held(grant.job_id);
    {
        std::lock_guard lock(frame.mu);
        // The hold was lost (and maybe taken again) since the lease was granted: these sums
        // are another epoch's, whose schedule may lease the range again. Not added.
        hold_lost = frame.hold_epoch != epoch;
        if (!hold_lost) {
            // Made (and its pages touched) once per frame, outside the measured per-report cost
            // that sizes the job's leases.
            if (!frame.acc)
                frame.acc = std::make_unique<FrameAccumulator>(job->row.width, job->row.height,
                                                               job->settings);
            const clock::time_point add_start = clock::now();
            RenderStats stats;
            stats.samples = header.samples();
            stats.rays = header.rays();
            stats.non_finite = header.non_finite();
            stats.vpl_candidates = header.vpl_candidates();
            stats.vpl_accepted = std::min(header.vpl_accepted(), header.vpl_candidates());
            frame.acc->add(grant.range, values, header.odd_sum_omitted(), header.odd_count(),
                           stats);
            frame.relative_error = frame.acc->relative_error();
            frame.non_finite = frame.acc->result().stats.non_finite;
            frame.record_error({elapsed, frame.acc->count(), frame.relative_error.load()});
            merged_count = frame.acc->count();
            merged_error = frame.relative_error.load();
            const clock::time_point checkpoint_start = clock::now();
            add_time = checkpoint_start - add_start;
            // The checkpoint (the frame's whole sums) is written by the periodic tick, at most
            // every checkpoint_interval, not here: the worker waits for this reply. Until then the
            // store records only what the last checkpoint holds, so a crash re-leases what merged
            // since, and nothing is counted twice. With checkpoint_seconds 0, after every report.
            frame.dirty = true;
            if (!frame.checkpoint_clock) frame.checkpoint_clock = clock_();
            if (checkpoint_now) {
                frame_files_.save_checkpoint(grant.job_id, grant.frame, frame, elapsed, "report");
                checkpoint_time = clock::now() - checkpoint_start;
            }
        }
    }
    if (hold_lost) {
        metrics_.report_dropped("hold_lost");
        Log("warn", "report_dropped").kv("lease", header.lease_id()).kv("reason", "hold_lost");
        return Status::OK;
    }
    {
        std::lock_guard lock(mu_);
        scheduler_.end_merge(grant);
        scheduler_.note_report_cost(grant.job_id, std::chrono::duration<double>(add_time).count());
        const double target = job->request.settings().target_error();
        if (target > 0 && merged_count >= kMinTargetErrorIterations && merged_error <= target) {
            scheduler_.close_frame(grant.job_id, grant.frame);
            Log("info", "target_error_reached")
                .kv("job", grant.job_id)
                .kv("frame", grant.frame)
                .kv("iterations", merged_count)
                .kv("relative_error", merged_error);
        }
        if (header.render_seconds() > 0) {
            v1::WorkerRates rates;
            rates.set_iterations_per_second(double(header.count()) / header.render_seconds());
            rates.set_samples_per_second(double(header.samples()) / header.render_seconds());
            rates.set_rays_per_second(double(header.rays()) / header.render_seconds());
            workers_.set_rates(grant.worker_id, rates);
        }
        // The job renders somewhere: earlier failures no longer count (failure_policy.h).
        job->failures.report_merged(grant.lease_id);
    }
    *merged = true;
    metrics_.report_merged(std::chrono::duration<double>(add_time).count(),
                           std::chrono::duration<double>(checkpoint_time).count());
    Log("info", "merged")
        .kv("lease", grant.lease_id)
        .kv("job", grant.job_id)
        .kv("frame", grant.frame)
        .kv("first", grant.range.first)
        .kv("end", grant.range.end)
        .kv("render_seconds", header.render_seconds())
        .kv("add_us", std::chrono::duration_cast<std::chrono::microseconds>(add_time).count())
        .kv("checkpoint_us",
            std::chrono::duration_cast<std::chrono::microseconds>(checkpoint_time).count());
    // The report's values are in the sums: free them before a completed frame's EXR is made.
    values.release();
    advance();
    return Status::OK;
}

std::shared_ptr<void> JobManager::report_slot(const std::string& lease_id) {
    std::shared_ptr<JobData> job;
    {
        std::lock_guard lock(mu_);
        if (std::optional<LeaseGrant> grant = scheduler_.find_lease(lease_id))
            job = find(grant->job_id);
    }
    if (!job) return nullptr;
    job->report_mu.lock();
    return std::shared_ptr<void>(job.get(), [job](void*) { job->report_mu.unlock(); });
}

}  // namespace render::server
