#pragma once

#include <cstdint>
#include <string>

namespace render {

// Everything that, together with the scene, determines a rendered image.
struct RenderSettings {
    std::string algorithm = "pt";
    int max_depth = -1;  // Mitsuba's meaning: segments per path, -1 = unbounded
    int rr_depth = 5;    // Russian roulette from this path depth on
    uint64_t seed = 0;   // job seed: part of every random stream key
    int threads = 0;     // 0 = all cores; never changes the image
};

// Counters of one render call; merged by addition.
struct RenderStats {
    uint64_t samples = 0;     // camera samples (pixels x iterations)
    uint64_t rays = 0;        // closest-hit plus shadow rays
    uint64_t non_finite = 0;  // NaN/Inf samples dropped before reaching the image

    RenderStats& operator+=(const RenderStats& o) {
        samples += o.samples;
        rays += o.rays;
        non_finite += o.non_finite;
        return *this;
    }
};

}  // namespace render
