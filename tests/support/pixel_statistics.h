#pragma once

// Mean of an image whose pixels all estimate the same value independently (furnaces, uniform
// media), with the standard error of that mean from the pixels' spread.

#include <algorithm>
#include <cmath>

#include "core/render/render_iterations.h"

namespace render::testing {

struct PixelStatistics {
    double mean = 0, standard_error = 0;
};

inline PixelStatistics pixel_statistics(const IterationResult& r, int channel) {
    const size_t n = r.sum.pixel_count();
    double sum = 0, sum2 = 0;
    for (size_t i = 0; i < n; ++i) {
        const double v = r.sum.channel(i, channel) / double(r.count);
        sum += v;
        sum2 += v * v;
    }
    const double mean = sum / n, var = std::max(0.0, sum2 / n - mean * mean);
    return {mean, std::sqrt(var / double(n - 1))};
}

}  // namespace render::testing
