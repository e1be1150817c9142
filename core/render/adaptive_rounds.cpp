#include "core/render/adaptive_rounds.h"

#include <stdexcept>

namespace render {

void AdaptiveSums::add_iteration(const std::vector<double>& rgb, uint64_t iteration,
                                 std::span<const uint8_t> active) {
    if (rgb.size() != 3 * count.size() || (!active.empty() && active.size() != count.size()))
        throw std::invalid_argument("AdaptiveSums::add_iteration: buffers of another size");
    // An inactive pixel's value is 0 (the pixel loop skipped it), so the exact sums may add
    // every pixel; only the counts need the mask.
    exact.add_iteration(rgb, iteration);
    const bool odd = iteration % 2 == 1;
    for (size_t p = 0; p < count.size(); ++p)
        if (active.empty() || active[p]) {
            ++count[p];
            if (odd) ++odd_count[p];
        }
}

void AdaptiveSums::add(const AdaptiveSums& other) {
    if (other.count.size() != count.size())
        throw std::invalid_argument("AdaptiveSums::add: sums of another size");
    exact.add(other.exact);
    for (size_t p = 0; p < count.size(); ++p) {
        count[p] += other.count[p];
        odd_count[p] += other.odd_count[p];
    }
}

void AdaptiveSums::add_counts(uint64_t first, uint64_t end, std::span<const uint8_t> active) {
    if (end < first || (!active.empty() && active.size() != count.size()))
        throw std::invalid_argument("AdaptiveSums::add_counts: bad range or mask");
    const uint64_t n = end - first, odd = end / 2 - first / 2;  // odd indices in [first, end)
    for (size_t p = 0; p < count.size(); ++p)
        if (active.empty() || active[p]) {
            count[p] += n;
            odd_count[p] += odd;
        }
}

std::vector<uint8_t> adaptive_round_mask(const AdaptiveSums& sums, int width, int height,
                                         const RenderSettings& settings) {
    AdaptiveMaskSettings mask;
    mask.threshold = settings.adaptive;
    // Nine pixels' estimates of the standard deviation; an active pixel keeps its neighbours
    // active (docs/reference/adaptive-sampling.md, "The norm").
    mask.error_window = 1;
    mask.spread = 1;
    return adaptive_active_mask(sums.exact, width, height, sums.count, sums.odd_count, mask);
}

}  // namespace render
