#include "core/image/metrics.h"

#include <cmath>
#include <stdexcept>

namespace render {

ImageComparison compare_images(const Image& test, const Image& reference) {
    if (test.width() != reference.width() || test.height() != reference.height())
        throw std::invalid_argument("images differ in size: " + std::to_string(test.width()) + "x" +
                                    std::to_string(test.height()) + " vs " +
                                    std::to_string(reference.width()) + "x" +
                                    std::to_string(reference.height()));
    ImageComparison result;
    std::array<double, 3> se{}, rel{}, diff{};
    size_t n = 0;
    for (size_t i = 0; i < test.pixel_count(); ++i) {
        Rgb a = test.at(i), b = reference.at(i);
        if (!a.is_finite() || !b.is_finite()) {
            ++result.non_finite;
            continue;
        }
        ++n;
        for (int c = 0; c < 3; ++c) {
            double d = double(a[c]) - double(b[c]);
            se[c] += d * d;
            // The 1e-2 term is the usual regulariser of relative MSE (Rousselle et al.).
            rel[c] += d * d / (double(b[c]) * b[c] + 1e-2);
            diff[c] += d;
        }
    }
    if (n == 0) return result;
    for (int c = 0; c < 3; ++c) {
        result.rmse[c] = std::sqrt(se[c] / n);
        result.relative_mse[c] = rel[c] / n;
        result.mean_difference[c] = diff[c] / n;
    }
    result.rmse_all = std::sqrt((se[0] + se[1] + se[2]) / (3.0 * n));
    result.relative_mse_all = (rel[0] + rel[1] + rel[2]) / (3.0 * n);
    return result;
}

}  // namespace render
