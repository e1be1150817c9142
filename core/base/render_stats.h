#pragma once

#include <cstdint>

// What a render call counted; merged by addition (a worker reports it with its sums).

namespace render {

// Counters of one render call; merged by addition.
struct RenderStats {
    uint64_t samples = 0;     // camera samples (pixels x iterations)
    uint64_t rays = 0;        // closest-hit plus shadow rays
    uint64_t non_finite = 0;  // NaN/Inf samples dropped before reaching the image
    // vpl with the importance-driven distribution: candidate and accepted VPLs.
    uint64_t vpl_candidates = 0, vpl_accepted = 0;

    RenderStats& operator+=(const RenderStats& o) {
        samples += o.samples;
        rays += o.rays;
        non_finite += o.non_finite;
        vpl_candidates += o.vpl_candidates;
        vpl_accepted += o.vpl_accepted;
        return *this;
    }
};

}  // namespace render
