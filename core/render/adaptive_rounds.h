#pragma once

// Adaptive sampling's rounds (docs/reference/adaptive-sampling.md): every pixel takes
// iterations [1, min_iterations]; after that, round k >= 1 is iterations
// (min + (k - 1) L, min + k L] for round length L, and its active pixels are a pure function of
// the exact sums of iterations [1, min + (k - 1) L] (core/render/adaptive_mask.h). The
// boundaries depend on the settings alone, so every process knows them without asking.

#include <cstdint>
#include <span>
#include <vector>

#include "core/image/fixed_point_sums.h"
#include "core/render/adaptive_mask.h"
#include "core/render/render_settings.h"

namespace render {

class AdaptiveRounds {
  public:
    explicit AdaptiveRounds(const RenderSettings& settings)
        : min_(settings.adaptive_min_iterations), length_(settings.adaptive_round) {}

    // 0 for iterations 1..min (every pixel), else 1, 2, ...
    uint64_t round_of(uint64_t iteration) const {
        return iteration <= min_ ? 0 : 1 + (iteration - min_ - 1) / length_;
    }
    // First iteration of round k (1-based), and its exclusive end.
    uint64_t first(uint64_t round) const {
        return round == 0 ? 1 : min_ + (round - 1) * length_ + 1;
    }
    uint64_t end(uint64_t round) const { return min_ + round * length_ + 1; }

  private:
    uint64_t min_, length_;
};

// The sums adaptive sampling adds beside the image's: the exact brightness sums the mask reads
// and each pixel's own iteration counts (an inactive pixel's mean divides by its own count).
// Merged by addition like the image (empty when the job is not adaptive).
struct AdaptiveSums {
    FixedPointSums exact;
    std::vector<uint64_t> count, odd_count;  // per pixel

    AdaptiveSums() = default;
    explicit AdaptiveSums(size_t pixels) : exact(pixels), count(pixels, 0), odd_count(pixels, 0) {}
    bool empty() const { return count.empty(); }
    // Adds iteration `iteration`'s image, taken by the pixels whose `active` entry is 1 (all,
    // when `active` is empty).
    void add_iteration(const std::vector<double>& rgb, uint64_t iteration,
                       std::span<const uint8_t> active);
    void add(const AdaptiveSums& other);
    // The counts of iterations [first, end), rendered within one round with the mask `active`
    // (all pixels when empty), without their sums: what a range adds to each pixel's counts
    // follows from its round's mask, so the server derives it rather than receiving it.
    void add_counts(uint64_t first, uint64_t end, std::span<const uint8_t> active);
};

// The mask (1 = active) of a round >= 1 from the sums of every iteration before it.
std::vector<uint8_t> adaptive_round_mask(const AdaptiveSums& sums, int width, int height,
                                         const RenderSettings& settings);

}  // namespace render
