#include "core/render/adaptive_mask.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace render {
namespace {

// |m_o - m_e| sqrt(n_o n_e) / n, the standard error of the pixel's mean; its mean in `mean`.
double pixel_standard_error(double total, double odd, uint64_t count, uint64_t odd_count,
                            double& mean) {
    const uint64_t even_count = count - odd_count;
    if (odd_count == 0 || even_count == 0 || odd_count > count) {
        mean = 0;
        return std::numeric_limits<double>::infinity();
    }
    const double n = double(count), n_odd = double(odd_count), n_even = double(even_count);
    const double mean_odd = odd / n_odd, mean_even = (total - odd) / n_even;
    mean = total / n;
    return std::abs(mean_odd - mean_even) * std::sqrt(n_odd * n_even) / n;
}

}  // namespace

double halves_relative_error(double sum, double odd_sum, uint64_t count, uint64_t odd_count,
                             double dark) {
    double mean = 0;
    const double standard_error = pixel_standard_error(sum, odd_sum, count, odd_count, mean);
    return standard_error / std::max(mean, dark);
}

double pixel_deviation(int64_t sum, int64_t odd_sum, uint64_t count, uint64_t odd_count) {
    double mean = 0;
    return pixel_standard_error(FixedPointSums::to_value(sum), FixedPointSums::to_value(odd_sum),
                                count, odd_count, mean) *
           std::sqrt(double(count));
}

std::vector<uint8_t> adaptive_active_mask(const FixedPointSums& sums, int width, int height,
                                          std::span<const uint64_t> count,
                                          std::span<const uint64_t> odd_count,
                                          const AdaptiveMaskSettings& settings) {
    const size_t pixels = size_t(width) * size_t(height);
    if (sums.pixel_count() != pixels || count.size() != pixels || odd_count.size() != pixels)
        throw std::invalid_argument("adaptive_active_mask: buffers of another size");
    // Every sum below runs over the pixels in a fixed order: the mask stays a pure function of
    // the exact sums.
    std::vector<double> deviation(pixels);
    double image_sum = 0;
    for (size_t p = 0; p < pixels; ++p) {
        deviation[p] = pixel_deviation(sums.sum(p), sums.odd_sum(p), count[p], odd_count[p]);
        if (count[p] > 0) image_sum += FixedPointSums::to_value(sums.sum(p)) / double(count[p]);
    }
    const double image_mean =
        std::max(image_sum / double(std::max<size_t>(pixels, 1)), settings.dark);
    std::vector<uint8_t> unconverged(pixels);
    const int w = std::max(settings.error_window, 0);
    for (int y = 0; y < height; ++y)
        for (int x = 0; x < width; ++x) {
            double squares = 0;
            int n = 0;
            for (int yy = std::max(0, y - w); yy <= std::min(height - 1, y + w); ++yy)
                for (int xx = std::max(0, x - w); xx <= std::min(width - 1, x + w); ++xx) {
                    const double d = deviation[size_t(yy) * width + xx];
                    squares += d * d;
                    ++n;
                }
            const size_t p = size_t(y) * width + x;
            const double sigma = std::max(std::sqrt(squares / n), settings.dark);
            // A pixel without iterations has an infinite noise per iteration: active.
            const double noise = count[p] == 0 ? std::numeric_limits<double>::infinity()
                                               : sigma / (double(count[p]) * image_mean);
            unconverged[p] = noise > settings.threshold;
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
