#include "core/scene/invalid_ray_tally.h"

#include <utility>

namespace render {
namespace {

thread_local std::shared_ptr<InvalidRayTally> t_tally;

}  // namespace

void set_thread_invalid_ray_tally(std::shared_ptr<InvalidRayTally> tally) {
    t_tally = std::move(tally);
}

void clear_thread_invalid_ray_tally(const InvalidRayTally* tally) {
    if (t_tally.get() == tally) t_tally.reset();
}

void count_thread_invalid_ray() {
    if (InvalidRayTally* tally = t_tally.get()) tally->add();
}

}  // namespace render
