#pragma once

// The invalid rays (core/scene/invalid_ray_tally.h) counted by the threads of one task arena:
// every thread that joins the arena counts into this tally until it leaves. A render's
// iterations run in its own arena (IterationRenderer), so the tally holds that render's invalid
// rays alone, whatever else renders the same scene in the process meanwhile (a worker's
// RenderStats::invalid_rays are its lease's). Arenas are not nested here: a thread works for
// one arena at a time.

#include <tbb/task_arena.h>
#include <tbb/task_scheduler_observer.h>

#include <cstdint>
#include <memory>

#include "core/scene/invalid_ray_tally.h"

namespace render {

class ArenaInvalidRayTally : public tbb::task_scheduler_observer {
  public:
    // Observes `arena` (which must outlive this) from construction on.
    explicit ArenaInvalidRayTally(tbb::task_arena& arena)
        : tbb::task_scheduler_observer(arena), tally_(std::make_shared<InvalidRayTally>()) {
        observe(true);
    }
    ~ArenaInvalidRayTally() override { observe(false); }

    // The rays counted so far: complete for the work the arena finished (a thread counts
    // directly into the tally while it is in the arena).
    uint64_t count() const { return tally_->count(); }

    void on_scheduler_entry(bool) override { set_thread_invalid_ray_tally(tally_); }
    void on_scheduler_exit(bool) override { clear_thread_invalid_ray_tally(tally_.get()); }

  private:
    std::shared_ptr<InvalidRayTally> tally_;
};

}  // namespace render
