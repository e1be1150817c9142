#pragma once

#include <cstdint>

// What a render call counted; merged by addition (a worker reports it with its sums).

namespace render {

// Counters of one render call; merged by addition.
struct RenderStats {
    uint64_t samples = 0;     // camera samples (pixels x iterations)
    uint64_t rays = 0;        // closest-hit plus shadow rays
    uint64_t non_finite = 0;  // NaN/Inf samples dropped before reaching the image
    // Rays Embree would not accept (non-finite, or beyond the scene limits), taken as misses
    // without reaching it (Scene::invalid_rays).
    uint64_t invalid_rays = 0;
    // vpl with the importance-driven distribution: candidate and accepted VPLs.
    uint64_t vpl_candidates = 0, vpl_accepted = 0;

    RenderStats& operator+=(const RenderStats& o) {
        samples += o.samples;
        rays += o.rays;
        non_finite += o.non_finite;
        invalid_rays += o.invalid_rays;
        vpl_candidates += o.vpl_candidates;
        vpl_accepted += o.vpl_accepted;
        return *this;
    }
};

}  // namespace render
