#pragma once

// Adaptive sampling's active-pixel mask (docs/reference/adaptive-sampling.md): after a round of
// iterations, which pixels take part in the next. A pure function of the merged exact sums
// (core/image/fixed_point_sums.h) and the pixels' iteration counts, so that every worker
// count, lease split and merge order gives the same mask (docs/design/design.md).

#include <cstdint>
#include <span>
#include <vector>

#include "core/image/fixed_point_sums.h"

namespace render {

struct AdaptiveMaskSettings {
    // A pixel converges when its estimated relative error is at most this.
    double threshold = 0.02;
    // Brightness (R + G + B) under which the error is taken relative to this value instead:
    // a black pixel's relative error is undefined, and a nearly black one is not worth
    // iterations for its relative error alone.
    double dark = 1e-3;
    // An unconverged pixel keeps the pixels within this many pixels (a square) active: one
    // pixel's error estimate has one degree of freedom and misses noise by chance.
    int spread = 1;
    // A pixel's error is the root mean square of the relative errors of the pixels within this
    // many pixels (a square, clipped at the frame's edge): one pixel's odd/even estimate has one
    // degree of freedom (it exceeds twice the true error one time in twenty), a 3 x 3 window's
    // nine. 0: the pixel's own estimate.
    int error_window = 0;
};

// The estimated relative error of one pixel's mean brightness from its exact sums: with n
// iterations of which n_o odd (n_e = n - n_o even), the odd and even means m_o, m_e differ with
// variance sigma^2 (1/n_o + 1/n_e), so the mean's standard error is estimated by
// |m_o - m_e| sqrt(n_o n_e) / n (half the difference for equal halves), divided by
// max(mean, dark). Infinity when either half is empty (the error is unknown).
double pixel_relative_error(int64_t sum, int64_t odd_sum, uint64_t count, uint64_t odd_count,
                            double dark);

// The mask (1 = active) of a width x height frame: pixels whose relative error exceeds the
// threshold, spread to their neighbours. `count` and `odd_count` are each pixel's iterations
// (one entry per pixel).
std::vector<uint8_t> adaptive_active_mask(const FixedPointSums& sums, int width, int height,
                                          std::span<const uint64_t> count,
                                          std::span<const uint64_t> odd_count,
                                          const AdaptiveMaskSettings& settings);

}  // namespace render
