// The job manager's side of the worker protocol: registration, leases, heartbeats, and the
// failures and refusals workers report, judged by the failure policy (server/failure_policy.h).

#include "server/job_manager.h"

#include <cmath>
#include <optional>

#include "core/util/log.h"
#include "server/job_manager_detail.h"
#include "server/submission_check.h"

namespace render::server {

using grpc::Status;
using namespace detail;

void JobManager::register_worker(const v1::RegisterWorkerRequest& request,
                                 v1::RegisterWorkerReply* reply) {
    std::string id = "w-" + random_hex(12);
    {
        std::lock_guard lock(mu_);
        workers_.add(id, request, unix_ms());
    }
    reply->set_worker_id(id);
    reply->set_heartbeat_seconds(options_.heartbeat_seconds);
    Log("info", "worker_registered")
        .kv("worker", id)
        .kv("host", request.host().substr(0, 256))
        .kv("threads", request.threads())
        .kv("version", request.version().substr(0, 256));
}

Status JobManager::lease(const v1::LeaseRequest& request, v1::LeaseReply* reply) {
    if (!is_safe_id(request.worker_id()))
        return invalid("worker_id is empty or malformed; call RegisterWorker first");
    std::optional<LeaseGrant> grant;
    {
        std::unique_lock lock(mu_);
        workers_.touch(request.worker_id(), unix_ms());
        grant = scheduler_.lease(request.worker_id(), [&](const std::string& job_id) {
            auto job = find(job_id);
            // On a shared store only the server that holds a job leases it.
            return job && (!holds(*job) || lacks_memory_for(*job, request.worker_id()));
        });
        // Leases that expired just now (the scheduler expires them on every call) are counted
        // here, not at the next tick: on a shared store their rows must go before this grant
        // is claimed, or claim_lease refuses the expired range handed out again, and the
        // worker waits an idle pause with the range queued.
        std::vector<std::string> expired;
        for (const LeaseGrant& lost : scheduler_.take_expired()) {
            lease_lost(lost);
            expired.push_back(lost.lease_id);
        }
        if (shared_ && !expired.empty()) {
            lock.unlock();  // a round trip: not with every other call waiting
            for (const std::string& id : expired)
                store_or_log("lease", id, [&] { store_.delete_lease(id); });
            lock.lock();
        }
        // A loss just counted may have failed the grant's job (its leases are void then).
        if (grant && is_terminal(scheduler_.state(grant->job_id))) grant.reset();
        if (!grant) {
            reply->set_granted(false);
            return Status::OK;
        }
        auto job = find(grant->job_id);
        if (job && job->row.state == int(JobState::Queued)) {
            job->row.state = int(JobState::Running);
            store_or_log("job", job->row.id,
                         [&] { store_.update_job_state(job->row.id, int(JobState::Running), ""); });
        }
        reply->set_granted(true);
        v1::Lease* l = reply->mutable_lease();
        l->set_lease_id(grant->lease_id);
        l->set_job_id(grant->job_id);
        l->set_frame(grant->frame);
        l->set_first_iteration(grant->range.first);
        l->set_end_iteration(grant->range.end);
        l->set_expires_in_seconds(options_.lease_timeout_seconds);
        if (job) {
            *l->mutable_settings() = job->request.settings();
            for (const auto& [k, v] : frame_defines(job->request, grant->frame))
                (*l->mutable_settings()->mutable_defines())[k] = v;
            *l->mutable_bundle() = job->request.bundle();
            if (!fill_lease_mask(*job, *grant, l)) {
                // The scheduler leases a round only once its mask is taken: never expected.
                scheduler_.release(grant->worker_id, grant->lease_id);
                Log("error", "lease_without_mask")
                    .kv("job", grant->job_id)
                    .kv("frame", grant->frame)
                    .kv("first", grant->range.first);
                reply->Clear();
                reply->set_granted(false);
                return Status::OK;
            }
        }
    }
    // The lease's row and log line are written after mu_ is released: every other call of
    // every worker waits for mu_ (farm_sim, docs/results/service-measurements.md). The row is
    // written before the worker has its lease (the reply is sent when this returns), so its
    // report's delete comes after it.
    if (shared_) {
        // Several servers: the database is the arbiter (docs/design/job-store.md, "Leasing").
        // The holder's scheduler alone hands out the job's ranges, so a refusal means a stale
        // row or a hold lost meanwhile: the range is not handed out.
        bool claimed = false;
        try {
            claimed = store_.claim_lease(
                {grant->lease_id, grant->worker_id, grant->job_id, grant->frame, grant->range});
        } catch (const std::exception& e) {
            Log("error", "store_failed").kv("lease", grant->lease_id).kv("error", e.what());
        }
        if (!claimed) {
            {
                std::lock_guard lock(mu_);
                scheduler_.release(grant->worker_id, grant->lease_id);
            }
            metrics_.lease_refused_by_store();
            Log("warn", "lease_refused_by_store")
                .kv("lease", grant->lease_id)
                .kv("job", grant->job_id)
                .kv("frame", grant->frame)
                .kv("first", grant->range.first)
                .kv("end", grant->range.end);
            reply->Clear();
            reply->set_granted(false);
            return Status::OK;
        }
    } else {
        store_or_log("lease", grant->lease_id, [&] {
            store_.insert_lease(grant->lease_id, grant->worker_id, grant->job_id, grant->frame,
                                grant->range);
        });
    }
    Log("info", "lease")
        .kv("lease", grant->lease_id)
        .kv("worker", grant->worker_id)
        .kv("job", grant->job_id)
        .kv("frame", grant->frame)
        .kv("first", grant->range.first)
        .kv("end", grant->range.end);
    return Status::OK;
}

Status JobManager::heartbeat(const v1::HeartbeatRequest& request, v1::HeartbeatReply* reply) {
    if (!is_safe_id(request.worker_id())) return invalid("worker_id is empty or malformed");
    if (request.failed_leases_size() > 64) return invalid("at most 64 failed leases per heartbeat");
    std::vector<std::string> ids(request.lease_ids().begin(), request.lease_ids().end());
    std::lock_guard lock(mu_);
    workers_.touch(request.worker_id(), unix_ms());
    if (request.has_rates()) {
        const v1::WorkerRates& r = request.rates();
        if (std::isfinite(r.iterations_per_second()) && std::isfinite(r.samples_per_second()) &&
            std::isfinite(r.rays_per_second()))
            workers_.set_rates(request.worker_id(), r);
    }
    if (request.has_rates() && request.rates().iterations_per_second() > 0)
        note_lease_progress(request.worker_id(), request.lease_ids());
    for (const v1::LeaseFailure& failure : request.failed_leases())
        lease_failed(request.worker_id(), failure);
    for (const std::string& id : scheduler_.heartbeat(request.worker_id(), ids))
        reply->add_cancelled_lease_ids(id);
    return Status::OK;
}

void JobManager::note_lease_progress(
    const std::string& worker_id,
    const google::protobuf::RepeatedPtrField<std::string>& lease_ids) {
    for (const std::string& id : lease_ids)
        if (std::optional<LeaseGrant> grant = scheduler_.find_lease(id);
            grant && grant->worker_id == worker_id)
            if (auto job = find(grant->job_id)) job->failures.lease_progressed(id);
}

void JobManager::lease_failed(const std::string& worker_id, const v1::LeaseFailure& failure) {
    const std::optional<LeaseGrant> grant = scheduler_.release(worker_id, failure.lease_id());
    if (!grant) return;  // not this worker's active lease: nothing to count
    // On a shared store the row goes with it (its range is claimed again when re-leased).
    if (shared_)
        store_or_log("lease", grant->lease_id, [&] { store_.delete_lease(grant->lease_id); });
    if (failure.memory_needed() > 0 && failure.memory_limit() > 0) {
        if (auto job = find(grant->job_id); job && !is_terminal(scheduler_.state(grant->job_id)))
            lease_refused_for_memory(worker_id, *job, failure);
        return;
    }
    metrics_.lease_failed();
    const std::string error = failure.error().substr(0, 2000);
    Log("warn", "lease_failed")
        .kv("lease", grant->lease_id)
        .kv("worker", worker_id)
        .kv("job", grant->job_id)
        .kv("error", error);
    auto job = find(grant->job_id);
    if (!job || is_terminal(scheduler_.state(grant->job_id))) return;
    job->failures.lease_failed(worker_id, grant->lease_id, error, failure.report_undelivered());
    fail_if_poison(*job, grant->job_id);
}

void JobManager::lease_refused_for_memory(const std::string& worker_id, JobData& job,
                                          const v1::LeaseFailure& failure) {
    metrics_.lease_refused_memory();
    workers_.set_memory_limit(worker_id, failure.memory_limit());
    job.failures.refused_for_memory(worker_id, failure.memory_limit(), failure.memory_needed(),
                                    failure.error().substr(0, 2000));
    Log("warn", "lease_refused_memory")
        .kv("lease", failure.lease_id())
        .kv("worker", worker_id)
        .kv("job", job.row.id)
        .kv("needed", failure.memory_needed())
        .kv("limit", failure.memory_limit());
}

bool JobManager::lacks_memory_for(const JobData& job, const std::string& worker_id) const {
    return job.failures.lacks_memory(worker_id, workers_.memory_limit(worker_id));
}

bool JobManager::memory_blocked(const JobData& job) const {
    if (!job.failures.refused_for_memory()) return false;
    // Live: seen within the lease timeout, on the wall clock.
    return job.failures.memory_blocked(
        workers_.live(unix_ms(), int64_t(options_.lease_timeout_seconds * 1000)));
}

void JobManager::fail_memory_blocked() {
    const TimePoint now = clock_();
    for (auto& [id, job] : jobs_) {
        if (!job->failures.refused_for_memory() || is_terminal(scheduler_.state(id))) continue;
        const std::optional<std::string> why = job->failures.memory_wait_verdict(
            memory_blocked(*job), now, options_.memory_wait_seconds);
        if (!why) continue;
        Log("error", "job_failed").kv("job", id).kv("error", *why);
        set_state(*job, JobState::Failed, *why);
    }
}

void JobManager::report_stream_idle(const std::string& lease_id) {
    std::lock_guard lock(mu_);
    const std::optional<LeaseGrant> found = scheduler_.find_lease(lease_id);
    if (!found) return;  // expired meanwhile (queued again by expiry) or already merged
    const std::optional<LeaseGrant> grant = scheduler_.release(found->worker_id, lease_id);
    if (!grant) return;
    store_or_log("lease", lease_id, [&] { store_.delete_lease(lease_id); });
    Log("warn", "report_stream_idle")
        .kv("lease", lease_id)
        .kv("worker", grant->worker_id)
        .kv("job", grant->job_id)
        .kv("first", grant->range.first)
        .kv("end", grant->range.end);
    auto job = find(grant->job_id);
    if (!job || is_terminal(scheduler_.state(grant->job_id))) return;
    job->failures.report_stream_idle(grant->worker_id, lease_id);
    fail_if_poison(*job, grant->job_id);
}

void JobManager::lease_lost(const LeaseGrant& grant) {
    Log("warn", "lease_lost")
        .kv("lease", grant.lease_id)
        .kv("worker", grant.worker_id)
        .kv("job", grant.job_id);
    auto job = find(grant.job_id);
    if (!job || is_terminal(scheduler_.state(grant.job_id))) return;
    job->failures.lease_lost(grant.worker_id, grant.lease_id);
    fail_if_poison(*job, grant.job_id);
}

void JobManager::fail_if_poison(JobData& job, const std::string& job_id) {
    const std::optional<std::string> why = job.failures.poison_verdict(workers_.size());
    if (!why) return;
    Log("error", "job_failed").kv("job", job_id).kv("error", *why);
    set_state(job, JobState::Failed, *why);
}

}  // namespace render::server
