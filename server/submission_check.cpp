#include "server/submission_check.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <memory>
#include <set>
#include <stdexcept>
#include <vector>

#include "core/base/error.h"
#include "core/base/memory_budget.h"
#include "core/render/algorithms.h"
#include "core/render/job_limits.h"
#include "core/render/render_options.h"
#include "core/scene/loader/scene_loader.h"
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

double seconds_since(std::chrono::steady_clock::time_point start) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace

std::map<std::string, std::string> frame_defines(const v1::SubmitJobRequest& request,
                                                 uint32_t frame) {
    std::map<std::string, std::string> defines(request.settings().defines().begin(),
                                               request.settings().defines().end());
    if (frame < uint32_t(request.frames_size()))
        for (const auto& [k, v] : request.frames(int(frame)).defines()) defines[k] = v;
    return defines;
}

Status check_bundle_assets(
    const v1::SubmitJobRequest& request,
    const std::function<std::optional<uint64_t>(const std::string& sha256)>& asset_size) {
    for (const v1::BundleFile& f : request.bundle().files()) {
        auto size = asset_size(f.sha256());
        if (!size)
            return Status(
                StatusCode::FAILED_PRECONDITION,
                "asset \"" + f.path() + "\" (sha256 " + f.sha256() + ") has not been uploaded");
        if (f.size() != 0 && *size != f.size())
            return Status(StatusCode::INVALID_ARGUMENT,
                          "bundle file \"" + f.path() + "\" declares " + std::to_string(f.size()) +
                              " bytes, the asset has " + std::to_string(*size));
    }
    return Status::OK;
}

SubmissionCheck check_submission(const v1::SubmitJobRequest& in, const fs::path& scene_dir,
                                 double validation_seconds) {
    ValidatedSubmission out;
    out.request = in;
    v1::SubmitJobRequest& request = out.request;
    out.frames = uint32_t(std::max(1, request.frames_size()));
    // The frame whose scene is being loaded or checked (errors name it and its overrides).
    int64_t loading_frame = -1;
    try {
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
        // Adaptive sampling is read by the pixel algorithms alone (the options table refuses it
        // for the others, as `render` does); its samples layer takes the place of --layers,
        // which IterationRenderer refuses beside it (docs/reference/adaptive-sampling.md).
        if (settings.adaptive > 0 && settings.layers != LayerMode::None)
            throw std::invalid_argument(
                "adaptive sampling (--adaptive) writes its own layer (samples); --layers is not "
                "supported with it");
        s->set_algorithm(settings.algorithm);
        service::set_request_options(*s, render_settings_options(settings));
        if (s->iterations() == 0 && s->time_budget_seconds() == 0)
            s->set_iterations(uint64_t(std::max(1, scene->settings.sample_count)));
        if (s->iterations() > kMaxIterations)
            throw std::invalid_argument("the scene's sample_count exceeds " +
                                        std::to_string(kMaxIterations));
        if (std::string e = check_job_iterations(s->iterations(), out.frames); !e.empty())
            throw std::invalid_argument(e);
        const int width = s->width() ? int(s->width()) : scene->camera().width();
        const int height = s->height() ? int(s->height()) : scene->camera().height();
        if (width < 1 || height < 1 || width > kMaxFilmResolution || height > kMaxFilmResolution)
            throw std::invalid_argument("the film " + std::to_string(width) + "x" +
                                        std::to_string(height) + " exceeds " +
                                        std::to_string(kMaxFilmResolution));
        s->set_width(uint32_t(width));
        s->set_height(uint32_t(height));
        // Every other frame's defines must give a scene that loads and that the algorithm
        // renders. Frames with the same defines as an earlier one give the same scene.
        // Loads cost time (a 320k-triangle OBJ takes about 0.4 s); an animation whose loads
        // would exceed validation_seconds, estimated from the average so far, is refused
        // before the budget is spent.
        std::set<std::map<std::string, std::string>> checked{frame_defines(request, 0)};
        std::vector<uint32_t> to_load;
        for (uint32_t i = 1; i < out.frames; ++i)
            if (checked.insert(frame_defines(request, i)).second) to_load.push_back(i);
        scene.reset();
        for (size_t k = 0; k < to_load.size(); ++k) {
            const uint32_t i = to_load[k];
            const double spent = seconds_since(validate_start);
            const double estimate = spent + spent / double(k + 1) * double(to_load.size() - k);
            if (estimate > validation_seconds)
                throw ValidationBudgetExceeded(
                    "frames: loading the scene of each of " + std::to_string(to_load.size() + 1) +
                    " distinct frames to validate them would take about " +
                    std::to_string(int64_t(std::ceil(estimate))) + " s (" +
                    std::to_string(spent / double(k + 1)) +
                    " s per frame so far), more than "
                    "the server's limit of " +
                    std::to_string(int64_t(std::ceil(validation_seconds))) +
                    " s (server --submit-validation-seconds): submit the animation as several "
                    "jobs of fewer frames");
            std::map<std::string, std::string> defines = frame_defines(request, i);
            loading_frame = i;
            std::unique_ptr<Scene> frame_scene = load_scene_within_memory(
                scene_dir / request.bundle().scene_path(), defines, scene_dir);
            check_algorithm_supports_scene(settings, *frame_scene);
            loading_frame = -1;
        }
        out.validate_seconds = seconds_since(validate_start);
    } catch (const ValidationBudgetExceeded& e) {
        SubmissionCheck refused;
        refused.rejection = {Status(StatusCode::RESOURCE_EXHAUSTED, e.what()),
                             kValidationBudgetReason, -1, e.what()};
        return refused;
    } catch (const std::exception& e) {
        return {std::nullopt, submission_error(in, scene_dir, loading_frame, e)};
    }
    return {std::move(out), {}};
}

SubmissionRejection submission_error(const v1::SubmitJobRequest& request, const fs::path& scene_dir,
                                     int64_t frame, const std::exception& e) {
    // Bad settings are the request's fault and say so; scene and load errors are prefixed.
    const bool scene = dynamic_cast<const SceneError*>(&e) != nullptr;
    const bool settings = !scene && dynamic_cast<const std::invalid_argument*>(&e) != nullptr;
    // Files are named as in the client's bundle, not by the store's own folder (which
    // would tell the client nothing and show the server's layout).
    const std::string what = with_bundle_paths(e.what(), scene_dir.string());
    // In an animation, the failing frame and its overrides come first.
    std::string frame_prefix;
    if (frame >= 0 && request.frames_size() > 1) {
        frame_prefix = "frame " + std::to_string(frame) + " (";
        std::string overrides;
        for (const auto& [k, v] : frame_overrides(request, uint32_t(frame)))
            overrides += (overrides.empty() ? "" : " ") + k + "=" + v;
        frame_prefix += (overrides.empty() ? "no overrides" : overrides) + "): ";
    }
    if (settings)
        return {Status(StatusCode::INVALID_ARGUMENT, frame_prefix + what), nullptr, frame, what};
    return {Status(StatusCode::INVALID_ARGUMENT,
                   frame_prefix + std::string(scene ? "scene error: " : "cannot load the scene: ") +
                       what),
            scene ? "scene" : "load", frame, what};
}

}  // namespace render::server
