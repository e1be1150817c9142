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
    // A pixel stays active while its noise per iteration, sigma / (n * image mean), exceeds
    // this: it stops after sigma / (threshold * image mean) iterations, a count proportional to
    // its standard deviation (docs/reference/adaptive-sampling.md, "The norm").
    double threshold = 0.02;
    // Floor of the image mean and of a pixel's standard deviation (brightness R + G + B): a
    // black image has no scale, and a pixel whose halves happen to agree exactly still takes
    // iterations as the threshold goes to 0 (consistency).
    double dark = 1e-3;
    // An active pixel keeps the pixels within this many pixels (a square) active: one pixel's
    // estimate misses the rare bright paths of a caustic by chance.
    int spread = 1;
    // A pixel's standard deviation is the root mean square of the estimates of the pixels
    // within this many pixels (a square, clipped at the frame's edge): one pixel's odd/even
    // estimate has one degree of freedom (it is below half the true value one time in three),
    // a 3 x 3 window's nine. 0: the pixel's own estimate.
    int error_window = 0;
};

// The estimated relative error of one pixel's mean brightness from its sums: with n
// iterations of which n_o odd (n_e = n - n_o even), the odd and even means m_o, m_e differ with
// variance sigma^2 (1/n_o + 1/n_e), so the mean's standard error is estimated by
// |m_o - m_e| sqrt(n_o n_e) / n (half the difference for equal halves), divided by
// max(mean, dark). Infinity when either half is empty (the error is unknown). The sums are
// values (FixedPointSums::to_value of exact sums, or the image's double sums: --target-error
// per pixel).
double halves_relative_error(double sum, double odd_sum, uint64_t count, uint64_t odd_count,
                             double dark);

// The estimated standard deviation of one iteration's brightness in a pixel: its mean's
// standard error (as above) times sqrt(n), i.e. |m_o - m_e| sqrt(n_o n_e / n). Infinity when
// either half is empty.
double pixel_deviation(int64_t sum, int64_t odd_sum, uint64_t count, uint64_t odd_count);

// The mask (1 = active) of a width x height frame: pixels whose noise per iteration exceeds the
// threshold, spread to their neighbours. `count` and `odd_count` are each pixel's iterations
// (one entry per pixel).
std::vector<uint8_t> adaptive_active_mask(const FixedPointSums& sums, int width, int height,
                                          std::span<const uint64_t> count,
                                          std::span<const uint64_t> odd_count,
                                          const AdaptiveMaskSettings& settings);

}  // namespace render
