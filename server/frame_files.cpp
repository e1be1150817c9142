#include "server/frame_files.h"

#include <algorithm>
#include <chrono>
#include <exception>
#include <stdexcept>

#include "core/render/image_metadata.h"
#include "core/util/log.h"
#include "server/submission_check.h"

namespace render::server {

namespace fs = std::filesystem;

void FrameData::record_error(const ErrorPoint& point) {
    if (history.size() >= kMaxHistory) {
        // Keep every other point: the plot keeps its shape over any length of render.
        size_t kept = 0;
        for (size_t i = 0; i < history.size(); i += 2) history[kept++] = history[i];
        history.resize(kept);
    }
    history.push_back(point);
}

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

FrameFiles::FrameFiles(fs::path store, JobStore& job_store, Scheduler::ClockFn clock,
                       double checkpoint_seconds)
    : store_(std::move(store)),
      job_store_(job_store),
      clock_(std::move(clock)),
      checkpoint_seconds_(checkpoint_seconds) {}

fs::path FrameFiles::checkpoint_path(const std::string& job_id, uint32_t frame) const {
    return store_ / "checkpoints" / job_id / (std::to_string(frame) + ".ckpt");
}

fs::path FrameFiles::result_path(const std::string& job_id, uint32_t frame) const {
    return store_ / "results" / job_id / (std::to_string(frame) + ".exr");
}

double FrameFiles::checkpoint_interval(const FrameData& frame) const {
    return std::max(checkpoint_seconds_, kCheckpointCostFactor * frame.last_checkpoint_seconds);
}

bool FrameFiles::checkpoint_due(const FrameData& frame, TimePoint now) const {
    return !frame.checkpoint_clock ||
           std::chrono::duration<double>(now - *frame.checkpoint_clock).count() >=
               checkpoint_interval(frame);
}

bool FrameFiles::load_checkpoint(const std::string& job_id, uint32_t index, int width, int height,
                                 size_t layers, FrameData& frame, FramePlan& plan) const {
    const fs::path ckpt = checkpoint_path(job_id, index);
    if (!fs::exists(ckpt)) return false;
    try {
        double elapsed = 0;
        auto acc = std::make_unique<FrameAccumulator>(FrameAccumulator::load(ckpt, &elapsed));
        if (acc->width() != width || acc->height() != height)
            throw std::runtime_error("checkpoint size differs from the job's");
        if (acc->layer_count() != layers)
            throw std::runtime_error("checkpoint layers differ from the job's");
        plan.merged = acc->ranges();
        plan.elapsed_seconds = std::max(plan.elapsed_seconds, elapsed);
        frame.relative_error = acc->relative_error();
        frame.non_finite = acc->result().stats.non_finite;
        frame.acc = std::move(acc);
        return true;
    } catch (const std::exception& e) {
        Log("error", "checkpoint_unreadable")
            .kv("job", job_id)
            .kv("frame", index)
            .kv("error", e.what());
        return false;
    }
}

bool FrameFiles::save_checkpoint(const std::string& job_id, uint32_t index, FrameData& frame,
                                 double elapsed, const char* reason) const {
    const TimePoint start = clock_();
    try {
        frame.acc->save(checkpoint_path(job_id, index), elapsed);
        job_store_.save_frame(job_id, index, frame.acc->ranges().ranges(), false, elapsed);
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

}  // namespace render::server
