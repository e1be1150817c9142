#pragma once

// Error metrics between two images of the same size, per channel and overall.

#include <array>
#include <string>

#include "core/image/image.h"

namespace render {

struct ImageComparison {
    std::array<double, 3> rmse{};             // sqrt(mean((a - b)^2))
    std::array<double, 3> relative_mse{};     // mean((a - b)^2 / (b^2 + 1e-2)), b = reference
    std::array<double, 3> mean_difference{};  // mean(a - b)
    double rmse_all = 0, relative_mse_all = 0;
    size_t non_finite = 0;  // pixels of either image with NaN or Inf (skipped)
};

// `reference` is the second image. Throws std::invalid_argument when the sizes differ.
ImageComparison compare_images(const Image& test, const Image& reference);

}  // namespace render
