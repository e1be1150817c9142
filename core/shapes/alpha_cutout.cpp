#include "core/shapes/alpha_cutout.h"

#include <cstdint>
#include <cstring>

#include "core/sampling/rng.h"

namespace render {

// SplitMix64's finaliser (core/sampling/rng.h) over the bits of each coordinate.
float AlphaCutout::ray_hash(const float org[3], const float dir[3], float t) {
    uint64_t h = 0x9e3779b97f4a7c15ULL;
    const auto add = [&h](float v) {
        uint32_t bits;
        std::memcpy(&bits, &v, sizeof bits);
        h = mix64(h ^ bits);
    };
    for (int i = 0; i < 3; ++i) add(org[i]);
    for (int i = 0; i < 3; ++i) add(dir[i]);
    add(t);
    return float(h >> 40) * 0x1p-24f;  // 24 bits: exactly representable, below 1
}

bool AlphaCutout::keeps_hit(Vec2 uv, const float org[3], const float dir[3], float t) const {
    const float a = alpha_.at(uv);
    if (a >= 1) return true;
    if (!(a > 0)) return false;  // zero, negative or NaN: a hole
    return ray_hash(org, dir, t) < a;
}

}  // namespace render
