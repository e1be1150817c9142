#pragma once

// Per-pixel sums that are exact, so that they do not depend on the order of addition: each
// iteration's pixel brightness (R + G + B) is rounded to a multiple of 2^-kFractionBits and
// added as an integer. The image's double sums are the same for any split of the iterations
// only up to their last bits (docs/design/design.md); a decision taken from them, such as
// adaptive sampling's active-pixel mask (core/render/adaptive_mask.h), could then flip with
// the number of workers. Integer sums make the decision a pure function of the set of
// iterations merged.

#include <cstdint>
#include <span>
#include <vector>

#include "core/image/image.h"

namespace render {

class FixedPointSums {
  public:
    // 2^-20 (~1e-6) resolution; one iteration's value is clamped to [0, 2^20) (the error of a
    // brighter pixel is still estimated, from clamped values), so 2^23 iterations never
    // overflow an int64.
    static constexpr int kFractionBits = 20;
    static constexpr double kMaxValue = double(int64_t(1) << 20);

    FixedPointSums() = default;
    explicit FixedPointSums(size_t pixels) : sum_(pixels, 0), odd_(pixels, 0) {}

    size_t pixel_count() const { return sum_.size(); }
    // One iteration's value of the brightness, rounded to the grid (NaN is 0).
    static int64_t quantize(double brightness);
    // Adds iteration `iteration`'s image (one value per pixel and channel, as the iteration
    // image of render_iterations) to the sums, and to the odd sums if `iteration` is odd.
    void add_iteration(const std::vector<double>& rgb, uint64_t iteration);
    // Adds another range's sums (exact).
    void add(const FixedPointSums& other);
    // The same from arrays, as a report or a checkpoint carries them: `sum` and `odd` (or
    // nothing, when `odd` is empty) added to pixels [first, first + sum.size()).
    void add(size_t first, std::span<const int64_t> sum, std::span<const int64_t> odd);
    // The largest sum one iteration adds to a pixel (kMaxValue on the grid).
    static constexpr int64_t kMaxQuantized = (int64_t(1) << (2 * kFractionBits)) - 1;

    // Every pixel's sum and odd sum, for reports and checkpoints.
    const std::vector<int64_t>& sums() const { return sum_; }
    const std::vector<int64_t>& odd_sums() const { return odd_; }

    int64_t sum(size_t pixel) const { return sum_[pixel]; }
    int64_t odd_sum(size_t pixel) const { return odd_[pixel]; }
    static double to_value(int64_t fixed) {
        return double(fixed) / double(int64_t(1) << kFractionBits);
    }

  private:
    std::vector<int64_t> sum_, odd_;
};

}  // namespace render
