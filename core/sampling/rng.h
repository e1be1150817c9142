#pragma once

// Random numbers that depend only on *what* is being sampled, never on who samples it.
//
// The iteration contract (DESIGN.md) requires every random number of iteration i to come from
// (job seed, frame, i, stream), where stream is a pixel index or a light-path index. We hash
// those four integers into the state and increment of a PCG32 generator (O'Neill 2014), so any
// thread, on any worker, that renders pixel p of iteration i draws the same numbers.

#include <cstdint>

#include "core/math/constants.h"
#include "core/math/vec.h"

namespace render {

// SplitMix64 finaliser: a bijective 64-bit mix with full avalanche.
constexpr uint64_t mix64(uint64_t z) {
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
}

// Hash of a sequence of integers (order matters).
constexpr uint64_t hash_combine(uint64_t h, uint64_t v) {
    return mix64(h ^ (v + 0x9e3779b97f4a7c15ULL + (h << 6) + (h >> 2)));
}

struct StreamKey {
    uint64_t seed = 0;
    uint32_t frame = 0;
    uint64_t iteration = 0;  // 1-based global iteration index
    uint64_t stream = 0;     // pixel index or light-path index
};

class Rng {
  public:
    explicit Rng(const StreamKey& key) {
        uint64_t h = mix64(key.seed ^ 0x5851f42d4c957f2dULL);
        h = hash_combine(h, key.frame);
        h = hash_combine(h, key.iteration);
        uint64_t stream_hash = hash_combine(h, key.stream);
        // Distinct increments give statistically independent PCG sequences; the state start
        // is decorrelated from the increment by a second hash.
        inc_ = (stream_hash << 1u) | 1u;
        state_ = 0;
        next_u32();
        state_ += mix64(stream_hash ^ 0xda942042e4dd58b5ULL);
        next_u32();
    }

    uint32_t next_u32() {
        uint64_t old = state_;
        state_ = old * 6364136223846793005ULL + inc_;
        uint32_t xorshifted = uint32_t(((old >> 18u) ^ old) >> 27u);
        uint32_t rot = uint32_t(old >> 59u);
        return (xorshifted >> rot) | (xorshifted << ((~rot + 1u) & 31));
    }

    // Uniform in [0, 1): 24 random mantissa bits, so 1 is never returned.
    float next_1d() { return float(next_u32() >> 8) * 0x1p-24f; }
    Vec2 next_2d() {
        float a = next_1d();
        return {a, next_1d()};
    }
    // x, y, z drawn in that order.
    Vec3 next_3d() {
        const float x = next_1d(), y = next_1d();
        return Vec3(x, y, next_1d());
    }

  private:
    uint64_t state_ = 0;
    uint64_t inc_ = 1;
};

}  // namespace render
