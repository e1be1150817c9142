#pragma once

// Where a thread counts the rays the scene's guard kept from Embree (core/scene/embree_ray.h),
// besides the scene's count over its life: the tally of the render the thread works for now.
// A render sets it for the threads of its own task arena (IterationRenderer, through
// ArenaInvalidRayTally), so two renders of one scene at once in one process each count only
// their own rays.

#include <atomic>
#include <cstdint>
#include <memory>

namespace render {

class InvalidRayTally {
  public:
    void add() { count_.fetch_add(1, std::memory_order_relaxed); }
    uint64_t count() const { return count_.load(std::memory_order_relaxed); }

  private:
    std::atomic<uint64_t> count_{0};
};

// The calling thread counts into `tally` from now on (null: into none). Held shared, so a
// thread that leaves a render's arena after the render ended never counts into freed memory.
void set_thread_invalid_ray_tally(std::shared_ptr<InvalidRayTally> tally);
// Clears the calling thread's tally if it is `tally` (a thread leaving the arena it counted
// for; it may have entered another arena since).
void clear_thread_invalid_ray_tally(const InvalidRayTally* tally);
// Counts one invalid ray in the calling thread's tally, if it has one (Scene's guard).
void count_thread_invalid_ray();

}  // namespace render
