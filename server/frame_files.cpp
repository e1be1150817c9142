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

void FrameData::set_lease_round_from_sums() {
    const bool adaptive = acc && acc->adaptive();
    lease_round = adaptive ? acc->round() : 0;
    lease_mask_sha256 = adaptive ? acc->mask_sha256() : std::string();
    lease_active_pixels = adaptive ? acc->active_pixels() : 0;
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

fs::path FrameFiles::checkpoint_path(const std::string& job_id, uint32_t frame,
                                     int64_t epoch) const {
    const std::string name = std::to_string(frame);
    return store_ / "checkpoints" / job_id /
           (epoch > 0 ? name + ".e" + std::to_string(epoch) + ".ckpt" : name + ".ckpt");
}

namespace {

// The epoch of a checkpoint file of `frame` ("N.ckpt": 0, "N.eE.ckpt": E), or -1 for another
// file (another frame's, a temporary one).
int64_t checkpoint_epoch(const std::string& file, uint32_t frame) {
    const std::string name = std::to_string(frame);
    if (file == name + ".ckpt") return 0;
    const std::string prefix = name + ".e", suffix = ".ckpt";
    if (file.size() <= prefix.size() + suffix.size() || file.rfind(prefix, 0) != 0 ||
        file.compare(file.size() - suffix.size(), suffix.size(), suffix) != 0)
        return -1;
    const std::string digits =
        file.substr(prefix.size(), file.size() - prefix.size() - suffix.size());
    if (digits.empty() || digits.size() > 18 ||
        digits.find_first_not_of("0123456789") != std::string::npos)
        return -1;
    return std::stoll(digits);
}

}  // namespace

fs::path FrameFiles::latest_checkpoint(const std::string& job_id, uint32_t frame,
                                       int64_t epoch) const {
    if (epoch <= 0) {
        const fs::path only = checkpoint_path(job_id, frame, 0);
        return fs::exists(only) ? only : fs::path();
    }
    fs::path best;
    int64_t best_epoch = -1;
    std::error_code ec;
    for (const auto& entry : fs::directory_iterator(store_ / "checkpoints" / job_id, ec)) {
        const int64_t e = checkpoint_epoch(entry.path().filename().string(), frame);
        if (e >= 0 && e < epoch && e > best_epoch) {
            best_epoch = e;
            best = entry.path();
        }
    }
    return best;
}

void FrameFiles::remove_checkpoints(const std::string& job_id, uint32_t frame) const {
    std::error_code ec;
    std::vector<fs::path> found;
    for (const auto& entry : fs::directory_iterator(store_ / "checkpoints" / job_id, ec))
        if (checkpoint_epoch(entry.path().filename().string(), frame) >= 0)
            found.push_back(entry.path());
    for (const fs::path& p : found) fs::remove(p, ec);
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

uint64_t adaptive_round_end(const RenderSettings& settings, uint64_t round) {
    return settings.adaptive > 0 ? AdaptiveRounds(settings).end(round) : 0;
}

bool FrameFiles::load_checkpoint(const std::string& job_id, uint32_t index, int width, int height,
                                 const RenderSettings& settings, FrameData& frame,
                                 FramePlan& plan) const {
    const size_t layers = TechniqueLayers::names(settings.layers).size();
    plan.round_end = adaptive_round_end(settings, 0);
    const fs::path ckpt = latest_checkpoint(job_id, index, frame.hold_epoch);
    if (ckpt.empty()) return false;
    try {
        double elapsed = 0;
        auto acc = std::make_unique<FrameAccumulator>(FrameAccumulator::load(ckpt, &elapsed));
        if (acc->width() != width || acc->height() != height)
            throw std::runtime_error("checkpoint size differs from the job's");
        if (acc->layer_count() != layers)
            throw std::runtime_error("checkpoint layers differ from the job's");
        const AdaptiveRounds job_rounds(settings);
        if (acc->adaptive() != (settings.adaptive > 0) ||
            (acc->adaptive() && (acc->rounds().first(1) != job_rounds.first(1) ||
                                 acc->rounds().end(1) != job_rounds.end(1))))
            throw std::runtime_error("checkpoint adaptive rounds differ from the job's");
        plan.merged = acc->ranges();
        if (acc->adaptive()) {
            plan.round_end = acc->rounds().end(acc->round());
            Log("info", "adaptive_round_restored")
                .kv("job", job_id)
                .kv("frame", index)
                .kv("round", acc->round())
                .kv("active_pixels", acc->active_pixels())
                .kv("iterations", acc->count());
        }
        plan.elapsed_seconds = std::max(plan.elapsed_seconds, elapsed);
        frame.relative_error = acc->relative_error();
        frame.non_finite = acc->result().stats.non_finite;
        frame.acc = std::move(acc);
        frame.set_lease_round_from_sums();
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
    if (frame.hold_epoch < 0) return false;  // a hold given up: its sums are void
    const TimePoint start = clock_();
    try {
        frame.acc->save(checkpoint_path(job_id, index, frame.hold_epoch), elapsed);
        job_store_.save_frame(job_id, index, frame.acc->ranges().ranges(), false, elapsed,
                              frame.hold_epoch);
        if (frame.hold_epoch > 0) {
            // The previous holds' checkpoints are superseded by this one (a lapsed holder that
            // writes one later leaves a file of an older epoch, never read after this).
            std::error_code ec;
            std::vector<fs::path> older;
            for (const auto& entry : fs::directory_iterator(store_ / "checkpoints" / job_id, ec)) {
                const int64_t e = checkpoint_epoch(entry.path().filename().string(), index);
                if (e >= 0 && e < frame.hold_epoch) older.push_back(entry.path());
            }
            for (const fs::path& p : older) fs::remove(p, ec);
        }
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
