// The job manager's wiring and the jobs themselves: construction and restore from the store,
// submit (checked by server/submission_check.h), state, cancel and priority.

#include "server/job_manager.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <map>
#include <set>
#include <stdexcept>
#include <string_view>

#include "core/render/render_options.h"
#include "core/util/log.h"
#include "server/job_manager_detail.h"
#include "server/store/open_job_store.h"
#include "server/store/sqlite_job_store.h"
#include "server/submission_check.h"
#include "service/request_options.h"

namespace render::server {

namespace fs = std::filesystem;
using grpc::Status;
using grpc::StatusCode;
using namespace detail;

// The settings a job renders with: its stored options are complete (submit resolved them),
// so the scene is not needed. A job stored by an older server may not resolve: then only its
// algorithm is known (no layers), which is all the server needs of it.
RenderSettings detail::job_settings(const v1::SubmitJobRequest& request) {
    try {
        return resolve_render_settings(request.settings().algorithm(),
                                       service::request_options(request.settings()),
                                       SceneSettings{});
    } catch (const std::invalid_argument&) {
        RenderSettings settings;
        settings.algorithm = request.settings().algorithm();
        return settings;
    }
}

JobManager::JobManager(ServerOptions options, Scheduler::ClockFn clock)
    : options_(options),
      clock_(clock),
      start_clock_(clock_()),
      start_unix_ms_(unix_ms()),
      owned_store_((fs::create_directories(options.store),
                    options.database.empty()
                        ? std::unique_ptr<JobStore>(
                              std::make_unique<SqliteJobStore>(options.store / "render.db"))
                        : open_job_store(options.database, options.store_connections))),
      store_(*owned_store_),
      frame_files_(options.store, store_, clock, options.checkpoint_seconds),
      assets_(options.store, options.max_store_size),
      client_streams_(options.streams),
      worker_streams_(options.streams),
      long_streams_(StreamLimits{options.streams.idle_seconds, SIZE_MAX}),
      scheduler_(SchedulerOptions{options.lease_timeout_seconds, options.target_lease_seconds,
                                  options.max_lease_seconds},
                 std::move(clock)),
      shared_(store_.shared()),
      server_id_("s-" + random_hex(12)) {
    fs::create_directories(options_.store / "jobs");
    fs::create_directories(options_.store / "checkpoints");
    fs::create_directories(options_.store / "results");
    // A spooled report's file is unlinked when made (server/report_values.h); where the file
    // system has no O_TMPFILE it had a name for an instant, which a crash may have left.
    std::error_code ignored;
    fs::remove_all(report_spool_folder(), ignored);
    restore();
}

JobManager::~JobManager() = default;

int64_t JobManager::now_unix_ms() const {
    return start_unix_ms_ +
           std::chrono::duration_cast<std::chrono::milliseconds>(clock_() - start_clock_).count();
}

std::shared_ptr<JobManager::JobData> JobManager::find(const std::string& job_id) {
    auto it = jobs_.find(job_id);
    return it == jobs_.end() ? nullptr : it->second;
}

void JobManager::restore() {
    if (shared_) {
        // Other servers may be running on this store: their leases and sums are theirs. The
        // jobs are read as the store records them and taken over by tick() (job_manager_holds).
        Log("info", "shared_store")
            .kv("server", server_id_)
            .kv("address", options_.advertise_address);
        // A dead server's leases are queued again when its hold has run out and another
        // server's next sync (a quarter of the hold, checked every tick) takes the job: within
        // the lease timeout only if the hold is short enough (docs/design/job-store.md, "How
        // long a lease stays lost").
        if (options_.hold_seconds * 1.25 + kTickSeconds > options_.lease_timeout_seconds)
            Log("warn", "hold_longer_than_lease_timeout")
                .kv("hold_seconds", options_.hold_seconds)
                .kv("lease_timeout", options_.lease_timeout_seconds)
                .kv("hint",
                    "a dead server's leases stay lost past the lease timeout: keep "
                    "--hold-seconds * 1.25 + 0.25 within --lease-timeout");
        sync_shared(true);
        return;
    }
    int voided = store_.clear_leases();
    if (voided > 0) Log("info", "leases_voided").kv("count", voided);
    next_sequence_ = store_.max_sequence() + 1;
    for (JobRow& row : store_.load_jobs()) {
        auto job = std::make_shared<JobData>();
        if (!job->request.ParseFromString(row.request)) {
            Log("error", "restore_failed").kv("job", row.id).kv("error", "unreadable request");
            continue;
        }
        job->settings = job_settings(job->request);
        job->row = std::move(row);
        const std::string& id = job->row.id;
        JobState state = JobState(job->row.state);
        if (is_terminal(state) && job->row.finished_unix_ms == 0) {
            // Finished before its store recorded finish times: its retention counts from now.
            job->row.finished_unix_ms = now_unix_ms();
            store_or_log("job", id, [&] {
                store_.update_job_state(id, job->row.state, job->row.error,
                                        job->row.finished_unix_ms);
            });
        }
        std::vector<FrameRow> rows = store_.load_frames(id);
        std::vector<FramePlan> plans;
        const v1::RenderSettings& s = job->request.settings();
        for (const FrameRow& fr : rows) {
            auto data = std::make_unique<FrameData>();
            FramePlan plan;
            plan.target = s.iterations();
            plan.budget_seconds = s.time_budget_seconds();
            plan.elapsed_seconds = fr.elapsed_seconds;
            plan.done = fr.done;
            if (fr.done || is_terminal(state)) {
                for (const Range& r : store_.merged_ranges(id, fr.index)) plan.merged.add(r);
            } else {
                // What the last checkpoint holds is merged; what merged after it is leased again.
                frame_files_.load_checkpoint(id, fr.index, job->row.width, job->row.height,
                                             job->settings, *data, plan);
                store_.set_merged_ranges(id, fr.index, plan.merged.ranges());
            }
            plans.push_back(std::move(plan));
            job->frames.push_back(std::move(data));
        }
        scheduler_.add_job(id, job->row.priority, uint64_t(job->row.sequence), state,
                           std::move(plans));
        Log("info", "job_restored")
            .kv("job", id)
            .kv("state", int(state))
            .kv("frames", job->frames.size());
        jobs_[id] = std::move(job);
    }
}

void JobManager::asset_added(const std::string& sha256, uint64_t size) {
    assets_.touch(sha256, now_unix_ms());
    store_.add_asset(sha256, size);
}

void JobManager::has_assets(const v1::HasAssetsRequest& request, v1::HasAssetsReply* reply) {
    const int64_t now = now_unix_ms();
    for (const std::string& sha : request.sha256())
        if (!assets_.touch(sha, now)) reply->add_missing(sha);
}

Status JobManager::submit(const v1::SubmitJobRequest& in, v1::Job* out) {
    if (Status st = check_submit_request(in, options_.max_job_assets); !st.ok()) return st;
    v1::SubmitJobRequest request = in;
    // The bundle's assets are pinned from before their presence is checked until the job is
    // stored (or refused): the asset sweep and job deletions (under mu_) pass them over.
    std::vector<std::string> pinned;
    for (const v1::BundleFile& f : request.bundle().files()) pinned.push_back(f.sha256());
    {
        std::lock_guard lock(mu_);
        for (const std::string& sha : pinned) ++submitting_assets_[sha];
    }
    struct Unpin {
        JobManager& m;
        const std::vector<std::string>& shas;
        ~Unpin() {
            std::lock_guard lock(m.mu_);
            for (const std::string& sha : shas)
                if (auto it = m.submitting_assets_.find(sha);
                    it != m.submitting_assets_.end() && --it->second <= 0)
                    m.submitting_assets_.erase(it);
        }
    } unpin{*this, pinned};
    if (Status st =
            check_bundle_assets(request, [&](const std::string& sha) { return assets_.size(sha); });
        !st.ok())
        return st;
    int64_t sequence;
    {
        std::lock_guard lock(mu_);
        // Several servers number their jobs from the store's highest sequence (two submits
        // at once on two servers may share one: the random suffix keeps the ids apart).
        if (shared_) next_sequence_ = std::max(next_sequence_, store_.max_sequence() + 1);
        sequence = next_sequence_++;
    }
    char prefix[32];
    std::snprintf(prefix, sizeof prefix, "job-%06lld-", (long long)sequence);
    std::string id = prefix + random_hex(6);
    fs::path job_dir = options_.store / "jobs" / id;
    fs::path scene_dir = job_dir / "scene";
    SubmissionCheck check;
    try {
        std::vector<std::pair<std::string, std::string>> files;
        for (const v1::BundleFile& f : request.bundle().files())
            files.emplace_back(f.path(), f.sha256());
        assets_.materialize(files, scene_dir);
        check = check_submission(request, scene_dir, options_.submit_validation_seconds);
    } catch (const std::exception& e) {
        check.rejection = submission_error(request, scene_dir, -1, e);
    }
    if (!check.job) {
        std::error_code ec;
        fs::remove_all(job_dir, ec);
        const SubmissionRejection& r = check.rejection;
        if (r.log_reason && std::string_view(r.log_reason) == kValidationBudgetReason)
            Log("warn", "submit_rejected").kv("reason", r.log_reason).kv("error", r.error);
        else if (r.log_reason)
            Log("warn", "submit_rejected")
                .kv("reason", r.log_reason)
                .kv("job_dir", job_dir.string())
                .kv("frame", r.frame)
                .kv("error", r.error);
        return r.status;
    }
    request = std::move(check.job->request);
    const int width = int(request.settings().width());
    const int height = int(request.settings().height());
    const double validate_seconds = check.job->validate_seconds;

    auto job = std::make_shared<JobData>();
    job->request = request;
    job->settings = job_settings(request);
    job->row.id = id;
    job->row.sequence = sequence;
    job->row.name = request.name();
    job->row.state = int(JobState::Queued);
    job->row.priority = request.priority();
    job->row.request = request.SerializeAsString();
    job->row.width = width;
    job->row.height = height;
    job->row.submitted_unix_ms = unix_ms();
    const uint32_t frame_count = check.job->frames;
    std::lock_guard lock(mu_);
    // Checked again under mu_ (the pins above keep deletions and the asset sweep off them, so
    // this only guards against a removal by another path): a job must never be stored with an
    // asset that workers could not fetch.
    for (const v1::BundleFile& f : request.bundle().files())
        if (!assets_.has(f.sha256())) {
            std::error_code ec;
            fs::remove_all(job_dir, ec);
            return Status(StatusCode::FAILED_PRECONDITION,
                          "asset \"" + f.path() + "\" (sha256 " + f.sha256() +
                              ") was deleted with another job while this one was submitted: "
                              "upload it again");
        }
    try {
        store_.insert_job(job->row, frame_count);
    } catch (const std::exception& e) {
        Log("error", "store_failed").kv("job", id).kv("error", e.what());
        return Status(StatusCode::INTERNAL, std::string("cannot store the job: ") + e.what());
    }
    std::vector<FramePlan> plans(frame_count);
    for (FramePlan& p : plans) {
        p.target = request.settings().iterations();
        p.budget_seconds = request.settings().time_budget_seconds();
        p.round_end = adaptive_round_end(job->settings, 0);
        job->frames.push_back(std::make_unique<FrameData>());
    }
    scheduler_.add_job(id, job->row.priority, uint64_t(sequence), JobState::Queued,
                       std::move(plans));
    jobs_[id] = job;
    fill_job(*job, out);
    Log("info", "job_submitted")
        .kv("job", id)
        .kv("name", request.name())
        .kv("algorithm", request.settings().algorithm())
        .kv("iterations", request.settings().iterations())
        .kv("time_budget", request.settings().time_budget_seconds())
        .kv("frames", frame_count)
        .kv("validate_seconds", validate_seconds)
        .kv("width", width)
        .kv("height", height)
        .kv("priority", request.priority());
    return Status::OK;
}

Status JobManager::get(const std::string& job_id, v1::Job* out) {
    if (shared_ && !known(job_id)) learn_job(job_id);
    std::lock_guard lock(mu_);
    auto job = find(job_id);
    if (!job) return job_not_found(job_id);
    fill_job(*job, out);
    return Status::OK;
}

void JobManager::list(v1::ListJobsReply* reply) {
    std::lock_guard lock(mu_);
    std::vector<const JobData*> ordered;
    for (const auto& [id, job] : jobs_) ordered.push_back(job.get());
    std::sort(ordered.begin(), ordered.end(),
              [](const JobData* a, const JobData* b) { return a->row.sequence < b->row.sequence; });
    for (const JobData* job : ordered) fill_job(*job, reply->add_jobs());
}

void JobManager::set_state(JobData& job, JobState state, const std::string& error) {
    scheduler_.set_state(job.row.id, state);
    job.row.state = int(state);
    job.row.error = error;
    if (is_terminal(state)) job.row.finished_unix_ms = now_unix_ms();
    store_or_log("job", job.row.id, [&] {
        store_.update_job_state(job.row.id, int(state), error,
                                is_terminal(state) ? job.row.finished_unix_ms : 0);
    });
}

bool JobManager::known(const std::string& job_id) {
    std::lock_guard lock(mu_);
    return find(job_id) != nullptr;
}

Status JobManager::cancel(const std::string& job_id, v1::Job* out) {
    if (shared_ && !known(job_id)) learn_job(job_id);
    std::lock_guard lock(mu_);
    auto job = find(job_id);
    if (!job) return job_not_found(job_id);
    JobState state = scheduler_.state(job_id);
    if (state == JobState::Done || state == JobState::Failed)
        return Status(
            StatusCode::FAILED_PRECONDITION,
            "job " + job_id + " has already " + (state == JobState::Done ? "finished" : "failed"));
    if (state != JobState::Cancelled) {
        set_state(*job, JobState::Cancelled, "");
        Log("info", "job_cancelled").kv("job", job_id);
    }
    fill_job(*job, out);
    return Status::OK;
}

Status JobManager::set_priority(const std::string& job_id, int priority, v1::Job* out) {
    std::lock_guard lock(mu_);
    auto job = find(job_id);
    if (!job) return job_not_found(job_id);
    if (is_terminal(scheduler_.state(job_id)))
        return Status(StatusCode::FAILED_PRECONDITION, "job " + job_id + " has ended");
    scheduler_.set_priority(job_id, priority);
    job->row.priority = priority;
    job->request.set_priority(priority);
    store_or_log("job", job_id, [&] { store_.update_job_priority(job_id, priority); });
    Log("info", "job_priority").kv("job", job_id).kv("priority", priority);
    fill_job(*job, out);
    return Status::OK;
}

}  // namespace render::server
