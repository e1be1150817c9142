#pragma once

#include <algorithm>
#include <cstdint>

namespace render::service {

// The pause between Lease calls that found no work: 0.3 s at first, growing by half up to 2 s
// while the farm stays idle, each pause jittered by +-20 % so that a farm started at once does
// not poll in step. An idle worker polling every 0.3 s cost the server twice the CPU of a busy
// one (farm_sim, docs/guide/service.md "How many workers one server carries"); 2 s is the most a
// new job waits for an idle farm to notice it.
class IdlePoll {
  public:
    explicit IdlePoll(uint64_t seed) : state_(seed | 1) {}
    double next() {
        double d = delay_ * (0.8 + 0.4 * uniform());
        delay_ = std::min(delay_ * 1.5, kMaxDelay);
        return d;
    }
    void reset() { delay_ = kFirstDelay; }

  private:
    static constexpr double kFirstDelay = 0.3, kMaxDelay = 2.0;
    double uniform() {  // xorshift64: jitter needs no quality, only distinct streams
        state_ ^= state_ << 13;
        state_ ^= state_ >> 7;
        state_ ^= state_ << 17;
        return double(state_ >> 11) * 0x1.0p-53;
    }
    double delay_ = kFirstDelay;
    uint64_t state_;
};

}  // namespace render::service
