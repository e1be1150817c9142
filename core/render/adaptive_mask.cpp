#include "core/render/adaptive_mask.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace render {

double pixel_relative_error(int64_t sum, int64_t odd_sum, uint64_t count, uint64_t odd_count,
                            double dark) {
    const uint64_t even_count = count - odd_count;
    if (odd_count == 0 || even_count == 0 || odd_count > count)
        return std::numeric_limits<double>::infinity();
    const double n = double(count), n_odd = double(odd_count), n_even = double(even_count);
    const double total = FixedPointSums::to_value(sum);
    const double odd = FixedPointSums::to_value(odd_sum);
    const double mean_odd = odd / n_odd, mean_even = (total - odd) / n_even;
    const double standard_error = std::abs(mean_odd - mean_even) * std::sqrt(n_odd * n_even) / n;
    return standard_error / std::max(total / n, dark);
}

std::vector<uint8_t> adaptive_active_mask(const FixedPointSums& sums, int width, int height,
                                          std::span<const uint64_t> count,
                                          std::span<const uint64_t> odd_count,
                                          const AdaptiveMaskSettings& settings) {
    const size_t pixels = size_t(width) * size_t(height);
    if (sums.pixel_count() != pixels || count.size() != pixels || odd_count.size() != pixels)
        throw std::invalid_argument("adaptive_active_mask: buffers of another size");
    std::vector<double> error(pixels);
    for (size_t p = 0; p < pixels; ++p)
        error[p] = pixel_relative_error(sums.sum(p), sums.odd_sum(p), count[p], odd_count[p],
                                        settings.dark);
    std::vector<uint8_t> unconverged(pixels);
    const int w = std::max(settings.error_window, 0);
    for (int y = 0; y < height; ++y)
        for (int x = 0; x < width; ++x) {
            // The window's errors are summed in a fixed order: the mask stays a pure function
            // of the exact sums.
            double squares = 0;
            int n = 0;
            for (int yy = std::max(0, y - w); yy <= std::min(height - 1, y + w); ++yy)
                for (int xx = std::max(0, x - w); xx <= std::min(width - 1, x + w); ++xx) {
                    const double e = error[size_t(yy) * width + xx];
                    squares += e * e;
                    ++n;
                }
            unconverged[size_t(y) * width + x] = std::sqrt(squares / n) > settings.threshold;
        }
    std::vector<uint8_t> active(pixels, 0);
    const int r = std::max(settings.spread, 0);
    for (int y = 0; y < height; ++y)
        for (int x = 0; x < width; ++x) {
            if (!unconverged[size_t(y) * width + x]) continue;
            for (int yy = std::max(0, y - r); yy <= std::min(height - 1, y + r); ++yy)
                for (int xx = std::max(0, x - r); xx <= std::min(width - 1, x + r); ++xx)
                    active[size_t(yy) * width + xx] = 1;
        }
    return active;
}

}  // namespace render
