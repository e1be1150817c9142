#pragma once

// A job's frames in memory and on disk: the merged sums of an unfinished frame and its
// checkpoint (written at most every checkpoint interval, so that a crash loses at most that
// much; docs/guide/service.md), and a finished frame's EXR.

#include <atomic>
#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "core/render/render_options.h"
#include "render.pb.h"
#include "server/accumulator.h"
#include "server/job_store.h"
#include "server/scheduler.h"

namespace render::server {

namespace v1 = ::render::v1;

// A frame's estimated relative error after a merged report, against its render time.
struct ErrorPoint {
    double seconds = 0;
    uint64_t iterations = 0;
    double relative_error = 1;
};

struct FrameData {
    std::mutex mu;
    std::unique_ptr<FrameAccumulator> acc;  // null until something merges, or when done
    std::atomic<double> relative_error{1.0};
    std::atomic<uint64_t> non_finite{0};
    std::vector<ErrorPoint> history;  // under mu (kept to kMaxHistory points)
    // Merged since the last checkpoint (set under mu; read without it to skip clean frames).
    std::atomic<bool> dirty{false};
    // When the interval to the next checkpoint started: the last checkpoint, or the first
    // merge of this run (under mu).
    std::optional<TimePoint> checkpoint_clock;
    double last_checkpoint_seconds = 0;  // how long the last checkpoint took (under mu)
    // On a shared store, the epoch of the job's hold these sums belong to (under mu): a report
    // accepted in another epoch is not added (job_manager_holds.cpp). 0 on a store of one.
    int64_t hold_epoch = 0;
    // An adaptive frame's current round as its leases name it, with its mask's SHA-256 and
    // active pixels (under the job manager's mu_, so that leasing never waits for frame.mu
    // while a report merges): set when a round opens and when the sums are restored or taken
    // over. The mask itself is the sums' (acc, under mu).
    uint64_t lease_round = 0;
    std::string lease_mask_sha256;
    uint64_t lease_active_pixels = 0;

    // Appends a point to the error history (mu held), thinning it when full.
    void record_error(const ErrorPoint& point);
    // The lease_* fields from the sums' current round (acc set; mu held, and the manager's mu_
    // when the frame is in use).
    void set_lease_round_from_sums();
};

// The end of an adaptive job's round `round` (FramePlan::round_end: no iteration at or past it
// is leased until the next round's mask is taken); 0 for a job that is not adaptive.
uint64_t adaptive_round_end(const RenderSettings& settings, uint64_t round);

// Points of a frame's error history kept (halved when full).
inline constexpr size_t kMaxHistory = 512;

// A frame is checkpointed at most every kCheckpointCostFactor times its last checkpoint's
// duration (and at most every checkpoint_seconds): checkpoints take at most 2 % of the time.
inline constexpr double kCheckpointCostFactor = 50;

// The EXR header of a frame's image, with the keys `render` writes (image_metadata) plus the
// job and frame.
std::map<std::string, std::string> frame_metadata(const v1::SubmitJobRequest& request,
                                                  const RenderSettings& settings,
                                                  const std::string& job_id, uint32_t index,
                                                  const FrameAccumulator& acc, double seconds);

// Where the store keeps frames (`store`/checkpoints/JOB/N.ckpt, `store`/results/JOB/N.exr),
// and the writing of checkpoints, recorded in the job store. On a shared store a frame's
// checkpoints are per hold, `N.eEPOCH.ckpt` (FrameData::hold_epoch): a server that lost its
// hold writes only its own epoch's file, never the new holder's (docs/design/job-store.md,
// "The write fence").
class FrameFiles {
  public:
    FrameFiles(std::filesystem::path store, JobStore& job_store, Scheduler::ClockFn clock,
               double checkpoint_seconds);

    // The checkpoint written in the hold of `epoch` (0: one server, `N.ckpt`).
    std::filesystem::path checkpoint_path(const std::string& job_id, uint32_t frame,
                                          int64_t epoch) const;
    // Removes every checkpoint of the frame (all epochs): the frame is finished.
    void remove_checkpoints(const std::string& job_id, uint32_t frame) const;
    std::filesystem::path result_path(const std::string& job_id, uint32_t frame) const;
    // Writes the frame's checkpoint (the file of its hold epoch) and records its ranges in the
    // store, fenced by that epoch; frame.mu held, and frame.acc set. Returns false (logged)
    // when it could not be written or the hold was lost (HoldLost).
    bool save_checkpoint(const std::string& job_id, uint32_t index, FrameData& frame,
                         double elapsed, const char* reason) const;
    // How long a frame waits between checkpoints: checkpoint_seconds, or kCheckpointCostFactor
    // times its last checkpoint's duration if longer (frame.mu held).
    double checkpoint_interval(const FrameData& frame) const;
    // A dirty frame's checkpoint is due at `now` (frame.mu held).
    bool checkpoint_due(const FrameData& frame, TimePoint now) const;
    // At restart or takeover: loads the frame's checkpoint, if any, into `frame` (its sums,
    // error and non-finite count) and `plan` (the ranges it holds, its render time if longer,
    // and an adaptive job's round: plan.round_end), provided it has the job's film size, layer
    // count and adaptive rounds (`settings`, the job's). With frame.hold_epoch E > 0 (a new
    // hold on a shared store) the checkpoint is the newest of an epoch before E. Returns false
    // without one, or when it cannot be read (logged): the frame then starts afresh (round 0).
    bool load_checkpoint(const std::string& job_id, uint32_t index, int width, int height,
                         const RenderSettings& settings, FrameData& frame, FramePlan& plan) const;

  private:
    // The newest checkpoint of the frame written before `epoch` (0: `N.ckpt` alone), or empty.
    std::filesystem::path latest_checkpoint(const std::string& job_id, uint32_t frame,
                                            int64_t epoch) const;

    std::filesystem::path store_;
    JobStore& job_store_;
    Scheduler::ClockFn clock_;
    double checkpoint_seconds_;
};

}  // namespace render::server
