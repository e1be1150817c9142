#include "server/job_manager.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <map>
#include <random>
#include <set>
#include <stdexcept>

#include "core/base/error.h"
#include "core/base/memory_budget.h"
#include "core/image/exr_io.h"
#include "core/render/algorithms.h"
#include "core/render/image_metadata.h"
#include "core/render/job_limits.h"
#include "core/render/render_options.h"
#include "core/scene/loader/scene_loader.h"
#include "core/util/log.h"
#include "server/validation.h"
#include "service/bundle_paths.h"
#include "service/request_options.h"

namespace render::server {

namespace fs = std::filesystem;
using grpc::Status;
using grpc::StatusCode;

namespace {

// The scene loaded within the memory this machine has available: a scene that would need more
// is refused at submit (a SceneError naming the file and the estimate) instead of exhausting
// the server.
std::unique_ptr<Scene> load_scene_within_memory(const fs::path& file,
                                                const std::map<std::string, std::string>& defines,
                                                const fs::path& confine_to) {
    SceneMemoryBudget budget(available_memory_bytes(),
                             "the memory available on the server's machine, MemAvailable in "
                             "/proc/meminfo");
    return load_scene(file, defines, confine_to);
}

// Points of a frame's error history kept (halved when full).
constexpr size_t kMaxHistory = 512;

// A frame is checkpointed at most every kCheckpointCostFactor times its last checkpoint's
// duration (and at most every checkpoint_seconds): checkpoints take at most 2 % of the time.
constexpr double kCheckpointCostFactor = 50;

int64_t unix_ms() {
    return std::chrono::duration_cast<std::chrono::milliseconds>(
               std::chrono::system_clock::now().time_since_epoch())
        .count();
}

std::string random_hex(int digits) {
    static thread_local std::mt19937_64 rng{std::random_device{}()};
    static const char* hex = "0123456789abcdef";
    std::string out;
    for (int i = 0; i < digits; ++i) out.push_back(hex[rng() & 15]);
    return out;
}

Status invalid(const std::string& message) {
    return Status(StatusCode::INVALID_ARGUMENT, message);
}

// The job store is the record of what survives a restart; a failed write is logged and the
// in-memory state goes on (the next checkpoint or restart reconciles it).
template <typename Write>
void store_or_log(const char* key, const std::string& id, Write&& write) {
    try {
        write();
    } catch (const std::exception& e) {
        Log("error", "store_failed").kv(key, id).kv("error", e.what());
    }
}

// The settings a job renders with: its stored options are complete (submit resolved them),
// so the scene is not needed. A job stored by an older server may not resolve: then only its
// algorithm is known (no layers), which is all the server needs of it.
RenderSettings job_settings(const v1::SubmitJobRequest& request) {
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

std::map<std::string, std::string> frame_defines(const v1::SubmitJobRequest& request,
                                                 uint32_t frame) {
    std::map<std::string, std::string> defines(request.settings().defines().begin(),
                                               request.settings().defines().end());
    if (frame < uint32_t(request.frames_size()))
        for (const auto& [k, v] : request.frames(int(frame)).defines()) defines[k] = v;
    return defines;
}

// Thrown when loading an animation's frames at submit would take too long.
struct ValidationBudgetExceeded : std::runtime_error {
    using std::runtime_error::runtime_error;
};

// The frame's own overrides (without the job's defines), sorted by name.
std::map<std::string, std::string> frame_overrides(const v1::SubmitJobRequest& request,
                                                   uint32_t frame) {
    if (frame >= uint32_t(request.frames_size())) return {};
    const auto& d = request.frames(int(frame)).defines();
    return std::map<std::string, std::string>(d.begin(), d.end());
}

// The EXR header of a frame's image, with the keys `render` writes (image_metadata) plus the
// job and frame.
std::map<std::string, std::string> frame_metadata(const v1::SubmitJobRequest& request,
                                                  const RenderSettings& settings,
                                                  const std::string& job_id, uint32_t index,
                                                  const FrameAccumulator& acc, double seconds) {
    const RenderStats& stats = acc.result().stats;
    RenderedImageFacts facts{
        request.bundle().scene_path(), acc.count(),      seconds,
        acc.relative_error(),          stats.non_finite, frame_defines(request, index)};
    facts.vpl_candidates = stats.vpl_candidates;
    facts.vpl_accepted = stats.vpl_accepted;
    facts.target_error = request.settings().target_error();
    std::map<std::string, std::string> metadata = image_metadata(settings, facts);
    metadata["render:job"] = job_id;
    metadata["render:frame"] = std::to_string(index);
    return metadata;
}

}  // namespace

JobManager::JobManager(ServerOptions options, Scheduler::ClockFn clock)
    : options_(options),
      clock_(clock),
      start_clock_(clock_()),
      start_unix_ms_(unix_ms()),
      store_((fs::create_directories(options.store), options.store / "render.db")),
      assets_(options.store, options.max_store_size),
      client_streams_(options.streams),
      worker_streams_(options.streams),
      long_streams_(StreamLimits{options.streams.idle_seconds, SIZE_MAX}),
      scheduler_(SchedulerOptions{options.lease_timeout_seconds, options.target_lease_seconds,
                                  options.max_lease_seconds},
                 std::move(clock)) {
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

fs::path JobManager::checkpoint_path(const std::string& job_id, uint32_t frame) const {
    return options_.store / "checkpoints" / job_id / (std::to_string(frame) + ".ckpt");
}

fs::path JobManager::result_path(const std::string& job_id, uint32_t frame) const {
    return options_.store / "results" / job_id / (std::to_string(frame) + ".exr");
}

std::shared_ptr<JobManager::JobData> JobManager::find(const std::string& job_id) {
    auto it = jobs_.find(job_id);
    return it == jobs_.end() ? nullptr : it->second;
}

void JobManager::restore() {
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
            fs::path ckpt = checkpoint_path(id, fr.index);
            if (fr.done || is_terminal(state)) {
                for (const Range& r : store_.merged_ranges(id, fr.index)) plan.merged.add(r);
            } else if (fs::exists(ckpt)) {
                try {
                    double elapsed = 0;
                    auto acc =
                        std::make_unique<FrameAccumulator>(FrameAccumulator::load(ckpt, &elapsed));
                    if (acc->width() != job->row.width || acc->height() != job->row.height)
                        throw std::runtime_error("checkpoint size differs from the job's");
                    if (acc->layer_count() != TechniqueLayers::names(job->settings.layers).size())
                        throw std::runtime_error("checkpoint layers differ from the job's");
                    plan.merged = acc->ranges();
                    plan.elapsed_seconds = std::max(plan.elapsed_seconds, elapsed);
                    data->relative_error = acc->relative_error();
                    data->non_finite = acc->result().stats.non_finite;
                    data->acc = std::move(acc);
                } catch (const std::exception& e) {
                    Log("error", "checkpoint_unreadable")
                        .kv("job", id)
                        .kv("frame", fr.index)
                        .kv("error", e.what());
                }
                store_.set_merged_ranges(id, fr.index, plan.merged.ranges());
            } else {
                store_.set_merged_ranges(id, fr.index, {});
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
    for (const v1::BundleFile& f : request.bundle().files()) {
        auto size = assets_.size(f.sha256());
        if (!size)
            return Status(
                StatusCode::FAILED_PRECONDITION,
                "asset \"" + f.path() + "\" (sha256 " + f.sha256() + ") has not been uploaded");
        if (f.size() != 0 && *size != f.size())
            return invalid("bundle file \"" + f.path() + "\" declares " + std::to_string(f.size()) +
                           " bytes, the asset has " + std::to_string(*size));
    }
    int64_t sequence;
    {
        std::lock_guard lock(mu_);
        sequence = next_sequence_++;
    }
    char prefix[32];
    std::snprintf(prefix, sizeof prefix, "job-%06lld-", (long long)sequence);
    std::string id = prefix + random_hex(6);
    fs::path job_dir = options_.store / "jobs" / id;
    fs::path scene_dir = job_dir / "scene";
    int width = 0, height = 0;
    const uint32_t frames_requested = uint32_t(std::max(1, request.frames_size()));
    // The frame whose scene is being loaded or checked (errors name it and its overrides).
    int64_t loading_frame = -1;
    double validate_seconds = 0;
    try {
        std::vector<std::pair<std::string, std::string>> files;
        for (const v1::BundleFile& f : request.bundle().files())
            files.emplace_back(f.path(), f.sha256());
        assets_.materialize(files, scene_dir);
        // Frame 0 validates the scene and gives the settings and film size of every frame;
        // the other frames are loaded and checked below.
        const auto validate_start = std::chrono::steady_clock::now();
        loading_frame = 0;
        std::unique_ptr<Scene> scene = load_scene_within_memory(
            scene_dir / request.bundle().scene_path(), frame_defines(request, 0), scene_dir);
        loading_frame = -1;
        v1::RenderSettings* s = request.mutable_settings();
        // The job stores the complete options its algorithm reads, resolved as `render` and
        // the worker resolve them (defaults, the scene's values, the request's options), so
        // every worker renders the same settings and the EXR header can record them.
        const RenderSettings settings =
            resolve_render_settings(job_algorithm(s->algorithm(), scene->settings.integrator),
                                    service::request_options(*s), scene->settings);
        check_algorithm_supports_scene(settings, *scene);
        s->set_algorithm(settings.algorithm);
        service::set_request_options(*s, render_settings_options(settings));
        if (s->iterations() == 0 && s->time_budget_seconds() == 0)
            s->set_iterations(uint64_t(std::max(1, scene->settings.sample_count)));
        if (s->iterations() > kMaxIterations)
            throw std::invalid_argument("the scene's sample_count exceeds " +
                                        std::to_string(kMaxIterations));
        if (std::string e = check_job_iterations(s->iterations(), frames_requested); !e.empty())
            throw std::invalid_argument(e);
        width = s->width() ? int(s->width()) : scene->camera().width();
        height = s->height() ? int(s->height()) : scene->camera().height();
        if (width < 1 || height < 1 || width > kMaxFilmResolution || height > kMaxFilmResolution)
            throw std::invalid_argument("the film " + std::to_string(width) + "x" +
                                        std::to_string(height) + " exceeds " +
                                        std::to_string(kMaxFilmResolution));
        s->set_width(uint32_t(width));
        s->set_height(uint32_t(height));
        // Every other frame's defines must give a scene that loads and that the algorithm
        // renders. Frames with the same defines as an earlier one give the same scene.
        // Loads cost time (a 320k-triangle OBJ takes about 0.4 s); an animation whose loads
        // would exceed options_.submit_validation_seconds, estimated from the average so far,
        // is refused before the budget is spent.
        std::set<std::map<std::string, std::string>> checked{frame_defines(request, 0)};
        std::vector<uint32_t> to_load;
        for (uint32_t i = 1; i < frames_requested; ++i)
            if (checked.insert(frame_defines(request, i)).second) to_load.push_back(i);
        scene.reset();
        for (size_t k = 0; k < to_load.size(); ++k) {
            const uint32_t i = to_load[k];
            const double spent =
                std::chrono::duration<double>(std::chrono::steady_clock::now() - validate_start)
                    .count();
            const double estimate = spent + spent / double(k + 1) * double(to_load.size() - k);
            if (estimate > options_.submit_validation_seconds)
                throw ValidationBudgetExceeded(
                    "frames: loading the scene of each of " + std::to_string(to_load.size() + 1) +
                    " distinct frames to validate them would take about " +
                    std::to_string(int64_t(std::ceil(estimate))) + " s (" +
                    std::to_string(spent / double(k + 1)) +
                    " s per frame so far), more than "
                    "the server's limit of " +
                    std::to_string(int64_t(std::ceil(options_.submit_validation_seconds))) +
                    " s (server --submit-validation-seconds): submit the animation as several "
                    "jobs of fewer frames");
            std::map<std::string, std::string> defines = frame_defines(request, i);
            loading_frame = i;
            std::unique_ptr<Scene> frame_scene = load_scene_within_memory(
                scene_dir / request.bundle().scene_path(), defines, scene_dir);
            check_algorithm_supports_scene(settings, *frame_scene);
            loading_frame = -1;
        }
        validate_seconds =
            std::chrono::duration<double>(std::chrono::steady_clock::now() - validate_start)
                .count();
    } catch (const ValidationBudgetExceeded& e) {
        std::error_code ec;
        fs::remove_all(job_dir, ec);
        Log("warn", "submit_rejected").kv("reason", "validation_budget").kv("error", e.what());
        return Status(StatusCode::RESOURCE_EXHAUSTED, e.what());
    } catch (const std::exception& e) {
        std::error_code ec;
        fs::remove_all(job_dir, ec);
        // Bad settings are the request's fault and say so; scene and load errors are prefixed.
        const bool scene = dynamic_cast<const SceneError*>(&e) != nullptr;
        const bool settings = !scene && dynamic_cast<const std::invalid_argument*>(&e) != nullptr;
        // Files are named as in the client's bundle, not by the store's own folder (which
        // would tell the client nothing and show the server's layout).
        const std::string what = with_bundle_paths(e.what(), scene_dir.string());
        // In an animation, the failing frame and its overrides come first.
        std::string frame_prefix;
        if (loading_frame >= 0 && request.frames_size() > 1) {
            frame_prefix = "frame " + std::to_string(loading_frame) + " (";
            std::string overrides;
            for (const auto& [k, v] : frame_overrides(request, uint32_t(loading_frame)))
                overrides += (overrides.empty() ? "" : " ") + k + "=" + v;
            frame_prefix += (overrides.empty() ? "no overrides" : overrides) + "): ";
        }
        if (settings) return invalid(frame_prefix + what);
        Log("warn", "submit_rejected")
            .kv("reason", scene ? "scene" : "load")
            .kv("job_dir", job_dir.string())
            .kv("frame", loading_frame)
            .kv("error", what);
        return invalid(frame_prefix +
                       std::string(scene ? "scene error: " : "cannot load the scene: ") + what);
    }

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
    const uint32_t frame_count = frames_requested;
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

void JobManager::fill_job(const JobData& job, v1::Job* out) const {
    out->Clear();
    out->set_id(job.row.id);
    out->set_name(job.row.name);
    out->set_state(shown_state(job));
    out->set_priority(job.row.priority);
    *out->mutable_settings() = job.request.settings();
    out->set_error(job.row.error);
    out->set_submitted_unix_ms(job.row.submitted_unix_ms);
    if (!is_terminal(scheduler_.state(job.row.id)) && memory_blocked(job))
        out->set_waiting(memory_waiting(job));
    const v1::RenderSettings& s = job.request.settings();
    for (uint32_t i = 0; i < job.frames.size(); ++i) {
        FrameProgress p = scheduler_.progress(job.row.id, i);
        v1::FrameStatus* f = out->add_frames();
        f->set_index(i);
        f->set_iterations_done(p.merged);
        f->set_iterations_target(p.target);
        f->set_relative_error(job.frames[i]->relative_error.load());
        double rate = p.elapsed_seconds > 0 ? double(p.merged) / p.elapsed_seconds : 0;
        f->set_iterations_per_second(rate);
        double eta = 0;
        if (!p.done) {
            if (p.target > 0 && rate > 0)
                eta = double(p.target - std::min(p.target, p.merged)) / rate;
            if (s.time_budget_seconds() > 0) {
                double left = std::max(0.0, s.time_budget_seconds() - p.elapsed_seconds);
                eta = p.target > 0 && rate > 0 ? std::min(eta, left) : left;
            }
        }
        f->set_eta_seconds(eta);
        f->set_done(p.done);
        f->set_render_seconds(p.elapsed_seconds);
    }
}

namespace {

// NOT_FOUND for a job id (cut to 80 characters: it is the caller's text).
Status job_not_found(const std::string& job_id) {
    return Status(StatusCode::NOT_FOUND, "job \"" + job_id.substr(0, 80) + "\" not found");
}

// NOT_FOUND for a frame index past a job's frames.
Status frame_not_found(const std::string& job_id, uint32_t index, size_t frames) {
    return Status(StatusCode::NOT_FOUND, "job " + job_id + " has no frame " +
                                             std::to_string(index) + " (" + std::to_string(frames) +
                                             " frames)");
}

}  // namespace

Status JobManager::get(const std::string& job_id, v1::Job* out) {
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

Status JobManager::cancel(const std::string& job_id, v1::Job* out) {
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

Status JobManager::result_file(const v1::FetchResultRequest& request, fs::path* file,
                               bool* temporary) {
    std::shared_ptr<JobData> job;
    FrameProgress progress;
    {
        std::lock_guard lock(mu_);
        job = find(request.job_id());
        if (!job) return job_not_found(request.job_id());
        if (request.frame() >= job->frames.size())
            return frame_not_found(request.job_id(), request.frame(), job->frames.size());
        progress = scheduler_.progress(request.job_id(), request.frame());
    }
    *temporary = false;
    if (progress.done) {
        *file = result_path(request.job_id(), request.frame());
        if (!fs::exists(*file))
            return Status(StatusCode::NOT_FOUND, "the result file of job " + request.job_id() +
                                                     " frame " + std::to_string(request.frame()) +
                                                     " is missing");
        return Status::OK;
    }
    if (!request.preview())
        return Status(StatusCode::FAILED_PRECONDITION,
                      "frame " + std::to_string(request.frame()) + " of job " + request.job_id() +
                          " is not done (" + std::to_string(progress.merged) +
                          " iterations so far); ask for a preview");
    FrameData& frame = *job->frames[request.frame()];
    std::lock_guard lock(frame.mu);
    if (!frame.acc || frame.acc->count() == 0) {
        // It may have finished meanwhile.
        fs::path done = result_path(request.job_id(), request.frame());
        if (fs::exists(done)) {
            *file = done;
            return Status::OK;
        }
        return Status(StatusCode::FAILED_PRECONDITION, "frame " + std::to_string(request.frame()) +
                                                           " of job " + request.job_id() +
                                                           " has no iterations yet");
    }
    *file = assets_.tmp_dir() / ("preview-" + request.job_id() + "-" +
                                 std::to_string(request.frame()) + "-" + random_hex(8) + ".exr");
    std::map<std::string, std::string> metadata =
        frame_metadata(job->request, job->settings, request.job_id(), request.frame(), *frame.acc,
                       progress.elapsed_seconds);
    metadata["render:preview"] = "1";
    try {
        write_frame_exr(*file, frame.acc->average(), metadata, frame.acc->layer_averages());
    } catch (const std::exception& e) {
        return Status(StatusCode::INTERNAL, std::string("cannot write the preview: ") + e.what());
    }
    *temporary = true;
    return Status::OK;
}

void JobManager::cluster_status(v1::ClusterStatusReply* reply) {
    std::lock_guard lock(mu_);
    for (const auto& [id, w] : workers_) {
        v1::WorkerStatus* s = reply->add_workers();
        s->set_worker_id(id);
        s->set_host(w.host);
        s->set_threads(w.threads);
        s->set_last_seen_unix_ms(w.last_seen_unix_ms);
        auto leases = scheduler_.worker_leases(id);
        if (!leases.empty()) s->set_lease_id(leases.front());
        s->set_active_leases(uint32_t(leases.size()));
        *s->mutable_rates() = w.rates;
    }
    for (const auto& [id, job] : jobs_) {
        const v1::JobState st = shown_state(*job);
        if (st == v1::JOB_STATE_QUEUED) reply->set_queued_jobs(reply->queued_jobs() + 1);
        if (st == v1::JOB_STATE_RUNNING) reply->set_running_jobs(reply->running_jobs() + 1);
        if (st == v1::JOB_STATE_WAITING) reply->set_waiting_jobs(reply->waiting_jobs() + 1);
    }
}

void JobManager::touch_worker(const std::string& worker_id) {
    WorkerInfo& w = workers_[worker_id];
    w.last_seen_unix_ms = unix_ms();
}

void JobManager::register_worker(const v1::RegisterWorkerRequest& request,
                                 v1::RegisterWorkerReply* reply) {
    std::string id = "w-" + random_hex(12);
    {
        std::lock_guard lock(mu_);
        WorkerInfo& w = workers_[id];
        w.host = request.host().substr(0, 256);
        w.threads = request.threads();
        w.version = request.version().substr(0, 256);
        w.last_seen_unix_ms = unix_ms();
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
        std::lock_guard lock(mu_);
        touch_worker(request.worker_id());
        grant = scheduler_.lease(request.worker_id(), [&](const std::string& job_id) {
            auto job = find(job_id);
            return job && lacks_memory_for(*job, request.worker_id());
        });
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
        }
    }
    // The lease's row and log line are written after mu_ is released: every other call of
    // every worker waits for mu_ (farm_sim, docs/service.md). The row is written before the
    // worker has its lease (the reply is sent when this returns), so its report's delete
    // comes after it.
    store_or_log("lease", grant->lease_id, [&] {
        store_.insert_lease(grant->lease_id, grant->worker_id, grant->job_id, grant->frame,
                            grant->range);
    });
    Log("info", "lease")
        .kv("lease", grant->lease_id)
        .kv("worker", grant->worker_id)
        .kv("job", grant->job_id)
        .kv("frame", grant->frame)
        .kv("first", grant->range.first)
        .kv("end", grant->range.end);
    return Status::OK;
}

// A job whose leases failed on this many distinct workers that reported an error (or on every
// worker the server knows, if fewer) is a poison job: it FAILS with the last error instead of
// being handed out for ever (issue 17: the same error from two workers).
constexpr size_t kMaxReportingWorkers = 2;
// Counting workers that lost a lease of the job (died or stopped heartbeating) as well, this
// many distinct ones fail it: a loss may be a machine taken away, so one more is asked for.
constexpr size_t kMaxFailedWorkers = 3;
// Workers lost after they reported rendering progress on the lease count only toward this
// larger limit: under a chaos soak (a worker SIGKILLed every 2 s among 3) healthy jobs failed
// after 3 such losses; a scene that crashes its workers mid-render still fails, later.
constexpr size_t kMaxLostRenderingWorkers = 10;

void JobManager::lease_failed(const std::string& worker_id, const v1::LeaseFailure& failure) {
    const std::optional<LeaseGrant> grant = scheduler_.release(worker_id, failure.lease_id());
    if (!grant) return;  // not this worker's active lease: nothing to count
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
    job->progressed_leases.erase(grant->lease_id);
    // An undelivered report is a transport fault after a render that worked: counted like a
    // lease lost while rendering, so one worker's unlucky link does not fail the job, while a
    // job whose reports no server accepts still fails at the larger limit.
    if (failure.report_undelivered())
        job->lost_rendering_workers.insert(worker_id);
    else
        job->failed_workers.insert(worker_id);
    job->last_failure = error;
    fail_if_poison(*job, grant->job_id);
}

void JobManager::lease_refused_for_memory(const std::string& worker_id, JobData& job,
                                          const v1::LeaseFailure& failure) {
    metrics_.lease_refused_memory();
    workers_[worker_id].memory_limit = failure.memory_limit();
    job.memory_refusals[worker_id] = failure.memory_limit();
    job.memory_needed = std::max(job.memory_needed, failure.memory_needed());
    job.memory_error = failure.error().substr(0, 2000);
    Log("warn", "lease_refused_memory")
        .kv("lease", failure.lease_id())
        .kv("worker", worker_id)
        .kv("job", job.row.id)
        .kv("needed", failure.memory_needed())
        .kv("limit", failure.memory_limit());
}

bool JobManager::lacks_memory_for(const JobData& job, const std::string& worker_id) const {
    if (job.memory_refusals.count(worker_id)) return true;
    auto w = workers_.find(worker_id);
    return job.memory_needed > 0 && w != workers_.end() && w->second.memory_limit > 0 &&
           w->second.memory_limit < job.memory_needed;
}

bool JobManager::memory_blocked(const JobData& job) const {
    if (job.memory_refusals.empty()) return false;
    const int64_t now = unix_ms();
    const auto live_ms = int64_t(options_.lease_timeout_seconds * 1000);
    bool any_live = false;
    for (const auto& [id, w] : workers_) {
        if (now - w.last_seen_unix_ms > live_ms) continue;
        any_live = true;
        if (!lacks_memory_for(job, id)) return false;
    }
    return any_live;
}

v1::JobState JobManager::shown_state(const JobData& job) const {
    const JobState state = scheduler_.state(job.row.id);
    // A job that was ever leased stays Running in the scheduler (and the store): shown as
    // RUNNING while nobody renders it, it would look stuck.
    if (!is_terminal(state) && memory_blocked(job) && !scheduler_.job_has_lease(job.row.id))
        return v1::JOB_STATE_WAITING;
    return v1::JobState(state);
}

std::string JobManager::memory_waiting(const JobData& job) const {
    uint64_t largest_limit = 0;
    for (const auto& [id, limit] : job.memory_refusals)
        largest_limit = std::max(largest_limit, limit);
    const size_t n = job.memory_refusals.size();
    char wait[32];
    std::snprintf(wait, sizeof wait, "%g", options_.memory_wait_seconds);
    return "waiting for a worker with more than " + format_bytes(largest_limit) +
           " of memory: the job needs at least " + format_bytes(job.memory_needed) +
           " (refused for memory by " + std::to_string(n) + " worker" + (n == 1 ? "" : "s") +
           "; it fails if none joins within " + wait + " s, server --memory-wait)";
}

void JobManager::fail_memory_blocked() {
    const TimePoint now = clock_();
    for (auto& [id, job] : jobs_) {
        if (job->memory_refusals.empty() || is_terminal(scheduler_.state(id))) continue;
        if (!memory_blocked(*job)) {
            job->memory_blocked_since.reset();
            continue;
        }
        if (!job->memory_blocked_since) job->memory_blocked_since = now;
        const double waited =
            std::chrono::duration<double>(now - *job->memory_blocked_since).count();
        if (waited < options_.memory_wait_seconds) continue;
        const size_t n = job->memory_refusals.size();
        char wait[32];
        std::snprintf(wait, sizeof wait, "%g", options_.memory_wait_seconds);
        const std::string why = "no worker has the memory for this job: refused for memory by " +
                                std::to_string(n) + " worker" + (n == 1 ? "" : "s") +
                                " and no live worker with more joined within " + wait +
                                " s (server --memory-wait); last refusal: " + job->memory_error;
        Log("error", "job_failed").kv("job", id).kv("error", why);
        set_state(*job, JobState::Failed, why);
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
    job->progressed_leases.erase(lease_id);
    job->lost_rendering_workers.insert(grant->worker_id);
    fail_if_poison(*job, grant->job_id);
}

void JobManager::lease_lost(const LeaseGrant& grant) {
    Log("warn", "lease_lost")
        .kv("lease", grant.lease_id)
        .kv("worker", grant.worker_id)
        .kv("job", grant.job_id);
    auto job = find(grant.job_id);
    if (!job || is_terminal(scheduler_.state(grant.job_id))) return;
    if (job->progressed_leases.erase(grant.lease_id))
        job->lost_rendering_workers.insert(grant.worker_id);
    else
        job->lost_workers.insert(grant.worker_id);
    fail_if_poison(*job, grant.job_id);
}

void JobManager::fail_if_poison(JobData& job, const std::string& job_id) {
    std::set<std::string> either = job.failed_workers;
    either.insert(job.lost_workers.begin(), job.lost_workers.end());
    // Reported failures: on every known worker (up to the limit) is enough; with lost leases
    // the limit itself is needed.
    const size_t needed_reported = std::clamp<size_t>(workers_.size(), 1, kMaxReportingWorkers);
    std::set<std::string> any = either;
    any.insert(job.lost_rendering_workers.begin(), job.lost_rendering_workers.end());
    if (job.failed_workers.size() < needed_reported && either.size() < kMaxFailedWorkers &&
        any.size() < kMaxLostRenderingWorkers)
        return;
    const size_t lost = job.lost_workers.size() + job.lost_rendering_workers.size();
    std::string why =
        "failed on " + std::to_string(any.size()) + " worker" + (any.size() == 1 ? "" : "s");
    if (lost > 0)
        why += " (" + std::to_string(lost) +
               " lost the lease: died or stopped heartbeating while rendering it)";
    why += job.last_failure.empty() ? std::string("; no worker reported an error")
                                    : "; last error: " + job.last_failure;
    Log("error", "job_failed").kv("job", job_id).kv("error", why);
    set_state(job, JobState::Failed, why);
}

void JobManager::note_lease_progress(
    const std::string& worker_id,
    const google::protobuf::RepeatedPtrField<std::string>& lease_ids) {
    for (const std::string& id : lease_ids)
        if (std::optional<LeaseGrant> grant = scheduler_.find_lease(id);
            grant && grant->worker_id == worker_id)
            if (auto job = find(grant->job_id)) job->progressed_leases.insert(id);
}

Status JobManager::heartbeat(const v1::HeartbeatRequest& request, v1::HeartbeatReply* reply) {
    if (!is_safe_id(request.worker_id())) return invalid("worker_id is empty or malformed");
    if (request.failed_leases_size() > 64) return invalid("at most 64 failed leases per heartbeat");
    std::vector<std::string> ids(request.lease_ids().begin(), request.lease_ids().end());
    std::lock_guard lock(mu_);
    touch_worker(request.worker_id());
    if (request.has_rates()) {
        const v1::WorkerRates& r = request.rates();
        if (std::isfinite(r.iterations_per_second()) && std::isfinite(r.samples_per_second()) &&
            std::isfinite(r.rays_per_second()))
            workers_[request.worker_id()].rates = r;
    }
    if (request.has_rates() && request.rates().iterations_per_second() > 0)
        note_lease_progress(request.worker_id(), request.lease_ids());
    for (const v1::LeaseFailure& failure : request.failed_leases())
        lease_failed(request.worker_id(), failure);
    for (const std::string& id : scheduler_.heartbeat(request.worker_id(), ids))
        reply->add_cancelled_lease_ids(id);
    return Status::OK;
}

Status JobManager::check_report(const v1::ReportHeader& header, size_t* values, size_t* layers,
                                bool* drop) {
    *drop = false;
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
    return Status::OK;
}

Status JobManager::report(const v1::ReportHeader& header, ReportValues&& values, bool* merged) {
    *merged = false;
    LeaseGrant grant;
    std::shared_ptr<JobData> job;
    MergeDecision decision;
    {
        std::lock_guard lock(mu_);
        decision = scheduler_.begin_merge(header.lease_id(), header.render_seconds(), &grant);
        if (decision == MergeDecision::Accept) job = find(grant.job_id);
    }
    store_or_log("lease", header.lease_id(), [&] { store_.delete_lease(header.lease_id()); });
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
    {
        std::lock_guard lock(frame.mu);
        // Made (and its pages touched) once per frame, outside the measured per-report cost
        // that sizes the job's leases.
        if (!frame.acc)
            frame.acc = std::make_unique<FrameAccumulator>(job->row.width, job->row.height,
                                                           job->settings.layers);
        const clock::time_point add_start = clock::now();
        RenderStats stats;
        stats.samples = header.samples();
        stats.rays = header.rays();
        stats.non_finite = header.non_finite();
        stats.vpl_candidates = header.vpl_candidates();
        stats.vpl_accepted = std::min(header.vpl_accepted(), header.vpl_candidates());
        frame.acc->add(grant.range, values, header.odd_sum_omitted(), header.odd_count(), stats);
        frame.relative_error = frame.acc->relative_error();
        frame.non_finite = frame.acc->result().stats.non_finite;
        if (frame.history.size() >= kMaxHistory) {
            // Keep every other point: the plot keeps its shape over any length of render.
            size_t kept = 0;
            for (size_t i = 0; i < frame.history.size(); i += 2)
                frame.history[kept++] = frame.history[i];
            frame.history.resize(kept);
        }
        frame.history.push_back({elapsed, frame.acc->count(), frame.relative_error.load()});
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
        if (options_.checkpoint_seconds <= 0) {
            save_checkpoint(grant.job_id, grant.frame, frame, elapsed, "report");
            checkpoint_time = clock::now() - checkpoint_start;
        }
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
            v1::WorkerRates& rates = workers_[grant.worker_id].rates;
            rates.set_iterations_per_second(double(header.count()) / header.render_seconds());
            rates.set_samples_per_second(double(header.samples()) / header.render_seconds());
            rates.set_rays_per_second(double(header.rays()) / header.render_seconds());
        }
        // The job renders somewhere: earlier failures were not the scene's fault (a poison job
        // never merges anything), so they no longer count toward failing it.
        job->failed_workers.clear();
        job->lost_workers.clear();
        job->lost_rendering_workers.clear();
        job->progressed_leases.erase(grant.lease_id);
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

void JobManager::tick() {
    advance();
    flush_checkpoints(false);
    apply_retention();
    collect_unreferenced_assets();
}

std::set<std::string> JobManager::assets_in_use(const std::string& except_job) const {
    std::set<std::string> used;
    for (const auto& [id, job] : jobs_)
        if (id != except_job)
            for (const v1::BundleFile& f : job->request.bundle().files()) used.insert(f.sha256());
    for (const auto& [sha, n] : submitting_assets_) used.insert(sha);
    return used;
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

void JobManager::advance() {
    std::vector<std::pair<std::string, uint32_t>> complete;
    {
        std::lock_guard lock(mu_);
        complete = scheduler_.tick();
        for (const LeaseGrant& grant : scheduler_.take_expired()) lease_lost(grant);
        fail_memory_blocked();
    }
    for (const auto& [job_id, frame] : complete) finish_frame(job_id, frame);
}

double JobManager::checkpoint_interval(const FrameData& frame) const {
    return std::max(options_.checkpoint_seconds,
                    kCheckpointCostFactor * frame.last_checkpoint_seconds);
}

bool JobManager::save_checkpoint(const std::string& job_id, uint32_t index, FrameData& frame,
                                 double elapsed, const char* reason) {
    const TimePoint start = clock_();
    try {
        frame.acc->save(checkpoint_path(job_id, index), elapsed);
        store_.save_frame(job_id, index, frame.acc->ranges().ranges(), false, elapsed);
    } catch (const std::exception& e) {
        Log("error", "checkpoint_failed")
            .kv("job", job_id)
            .kv("frame", index)
            .kv("error", e.what());
        frame.checkpoint_clock = clock_();  // tried again an interval later, not at every tick
        return false;
    }
    frame.dirty = false;
    frame.checkpoint_clock = clock_();
    frame.last_checkpoint_seconds =
        std::chrono::duration<double>(*frame.checkpoint_clock - start).count();
    Log("info", "checkpoint")
        .kv("job", job_id)
        .kv("frame", index)
        .kv("reason", reason)
        .kv("iterations", frame.acc->count())
        .kv("us", int64_t(frame.last_checkpoint_seconds * 1e6))
        .kv("next_in_seconds", checkpoint_interval(frame));
    return true;
}

void JobManager::flush_checkpoints(bool all) {
    struct Due {
        std::shared_ptr<JobData> job;
        std::string id;
        uint32_t index;
        double elapsed;
    };
    std::vector<Due> due;
    {
        std::lock_guard lock(mu_);
        for (const auto& [id, job] : jobs_) {
            if (is_terminal(scheduler_.state(id))) continue;
            for (uint32_t i = 0; i < job->frames.size(); ++i)
                if (job->frames[i]->dirty.load())
                    due.push_back({job, id, i, scheduler_.progress(id, i).elapsed_seconds});
        }
    }
    const TimePoint now = clock_();
    for (const Due& d : due) {
        FrameData& frame = *d.job->frames[d.index];
        std::lock_guard lock(frame.mu);
        if (!frame.dirty || !frame.acc) continue;
        if (!all && frame.checkpoint_clock &&
            std::chrono::duration<double>(now - *frame.checkpoint_clock).count() <
                checkpoint_interval(frame))
            continue;
        save_checkpoint(d.id, d.index, frame, d.elapsed, all ? "shutdown" : "interval");
    }
}

void JobManager::finish_frame(const std::string& job_id, uint32_t index) {
    std::lock_guard finish_lock(finish_mu_);
    std::shared_ptr<JobData> job;
    FrameProgress progress;
    {
        std::lock_guard lock(mu_);
        job = find(job_id);
        progress = scheduler_.progress(job_id, index);
    }
    if (!job) return;
    FrameData& frame = *job->frames[index];
    std::string error;
    std::vector<Range> ranges;  // what the EXR holds
    {
        std::lock_guard lock(frame.mu);
        if (!frame.acc) {
            error = "frame " + std::to_string(index) + " has no merged sums";
        } else {
            const std::map<std::string, std::string> metadata = frame_metadata(
                job->request, job->settings, job_id, index, *frame.acc, progress.elapsed_seconds);
            try {
                write_frame_exr(result_path(job_id, index), frame.acc->average(), metadata,
                                frame.acc->layer_averages());
                frame.relative_error = frame.acc->relative_error();
                ranges = frame.acc->ranges().ranges();
                frame.acc.reset();
                frame.dirty = false;
            } catch (const std::exception& e) {
                error = std::string("cannot write the result: ") + e.what();
            }
        }
    }
    std::lock_guard lock(mu_);
    if (!error.empty()) {
        Log("error", "frame_failed").kv("job", job_id).kv("frame", index).kv("error", error);
        set_state(*job, JobState::Failed, error);
        return;
    }
    bool job_done = scheduler_.finish_frame(job_id, index);
    store_or_log("job", job_id, [&] {
        store_.save_frame(job_id, index, ranges, true, progress.elapsed_seconds);
        std::error_code ec;
        fs::remove(checkpoint_path(job_id, index), ec);
    });
    Log("info", "frame_done")
        .kv("job", job_id)
        .kv("frame", index)
        .kv("iterations", progress.merged)
        .kv("seconds", progress.elapsed_seconds)
        .kv("relative_error", frame.relative_error.load());
    if (job_done) {
        set_state(*job, JobState::Done, "");
        Log("info", "job_done").kv("job", job_id);
    }
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

Status JobManager::preview_image(const std::string& job_id, uint32_t index, Image* image) {
    std::shared_ptr<JobData> job;
    FrameProgress progress;
    {
        std::lock_guard lock(mu_);
        job = find(job_id);
        if (!job) return job_not_found(job_id);
        if (index >= job->frames.size()) return frame_not_found(job_id, index, job->frames.size());
        progress = scheduler_.progress(job_id, index);
    }
    FrameData& frame = *job->frames[index];
    {
        std::lock_guard lock(frame.mu);
        if (frame.acc && frame.acc->count() > 0) {
            *image = frame.acc->average();
            return Status::OK;
        }
    }
    const fs::path done = result_path(job_id, index);
    if (fs::exists(done)) {
        try {
            *image = read_image(done);
            return Status::OK;
        } catch (const std::exception& e) {
            return Status(StatusCode::INTERNAL, e.what());
        }
    }
    return Status(StatusCode::FAILED_PRECONDITION, "frame " + std::to_string(index) + " of job " +
                                                       job_id + " has no iterations yet");
}

Status JobManager::error_history(const std::string& job_id, uint32_t index,
                                 std::vector<ErrorPoint>* points) {
    std::shared_ptr<JobData> job;
    {
        std::lock_guard lock(mu_);
        job = find(job_id);
        if (!job) return job_not_found(job_id);
        if (index >= job->frames.size()) return frame_not_found(job_id, index, job->frames.size());
    }
    FrameData& frame = *job->frames[index];
    std::lock_guard lock(frame.mu);
    *points = frame.history;
    return Status::OK;
}

std::string JobManager::metrics_text() {
    MetricsSnapshot s;
    {
        std::lock_guard lock(mu_);
        const int64_t now = unix_ms();
        const auto connected_ms = int64_t(options_.lease_timeout_seconds * 1000);
        for (const auto& [id, w] : workers_) {
            if (now - w.last_seen_unix_ms > connected_ms) continue;
            WorkerSnapshot ws;
            ws.id = id;
            ws.host = w.host;
            ws.threads = w.threads;
            ws.iterations_per_second = w.rates.iterations_per_second();
            ws.samples_per_second = w.rates.samples_per_second();
            ws.rays_per_second = w.rates.rays_per_second();
            ws.active_leases = uint32_t(scheduler_.worker_leases(id).size());
            s.workers.push_back(std::move(ws));
        }
        for (const auto& [id, job] : jobs_) {
            const JobState state = scheduler_.state(id);
            const size_t shown = size_t(shown_state(*job));
            if (shown < s.jobs_by_state.size()) ++s.jobs_by_state[shown];
            if (is_terminal(state)) continue;
            JobSnapshot js;
            js.id = id;
            js.relative_error = 0;
            if (memory_blocked(*job)) js.memory_wanted_bytes = double(job->memory_needed);
            for (uint32_t i = 0; i < job->frames.size(); ++i) {
                const FrameProgress p = scheduler_.progress(id, i);
                if (!p.done && p.elapsed_seconds > 0)
                    js.iterations_per_second += double(p.merged) / p.elapsed_seconds;
                js.relative_error =
                    std::max(js.relative_error, job->frames[i]->relative_error.load());
            }
            s.jobs.push_back(std::move(js));
        }
        s.queued_iterations = scheduler_.queued_iterations();
        s.asset_store_bytes = assets_.stored_bytes();
        s.active_leases = scheduler_.active_lease_count();
        s.leases = scheduler_.lease_counters();
    }
    return metrics_.exposition(s);
}

void JobManager::checkpoint_all() {
    flush_checkpoints(true);
    std::lock_guard lock(mu_);
    for (const auto& [id, job] : jobs_) {
        if (is_terminal(scheduler_.state(id))) continue;
        for (uint32_t i = 0; i < job->frames.size(); ++i) {
            FrameProgress p = scheduler_.progress(id, i);
            if (p.done) continue;
            store_or_log("job", id, [&] { store_.update_frame(id, i, false, p.elapsed_seconds); });
        }
    }
    Log("info", "checkpointed");
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
