#include "core/image/variance_layers.h"

#include <cmath>
#include <limits>

namespace render {

double variance_of_mean(double sum, double sum_squares, uint64_t count) {
    if (count < 2) return 0.0;
    if (!std::isfinite(sum_squares)) return std::numeric_limits<double>::infinity();
    const double n = double(count);
    const double deviations = sum_squares - sum * (sum / n);
    // Summing N terms in any order errs by at most (N - 1) eps times the sum of their
    // magnitudes: Q by (N - 1) eps Q, and S^2 / N by about 2 (N - 1) eps Q (Cauchy-Schwarz:
    // (sum |v|)^2 / N <= Q). Below that bound the difference is rounding, not variance.
    const double rounding = 4.0 * n * std::numeric_limits<double>::epsilon() * sum_squares;
    if (!(deviations > rounding)) return 0.0;
    return deviations / (n - 1.0) / n;
}

float finite_image_value(double value) {
    constexpr double kMax = std::numeric_limits<float>::max();
    if (std::isnan(value)) return 0.0f;
    if (value > kMax) return float(kMax);
    if (value < -kMax) return float(-kMax);
    return float(value);
}

std::vector<NamedLayer> variance_layers(const AccumulationBuffer& sum,
                                        const AccumulationBuffer& odd_sum,
                                        const AccumulationBuffer& sum_squares, uint64_t count,
                                        uint64_t odd_count) {
    const int width = sum.width(), height = sum.height();
    Image variance(width, height), odd(width, height), even(width, height);
    const std::vector<double>& s = sum.values();
    const std::vector<double>& o = odd_sum.values();
    const std::vector<double>& q = sum_squares.values();
    const uint64_t even_count = count - odd_count;
    const double odd_scale = odd_count > 0 ? 1.0 / double(odd_count) : 0.0;
    const double even_scale = even_count > 0 ? 1.0 / double(even_count) : 0.0;
    float* v_out = variance.data();
    float* o_out = odd.data();
    float* e_out = even.data();
    for (size_t i = 0; i < s.size(); ++i) {
        v_out[i] = finite_image_value(variance_of_mean(s[i], q[i], count));
        o_out[i] = finite_image_value(o[i] * odd_scale);
        e_out[i] = finite_image_value((s[i] - o[i]) * even_scale);
    }
    std::vector<NamedLayer> layers;
    layers.push_back({"variance", std::move(variance)});
    layers.push_back({"odd_half", std::move(odd)});
    layers.push_back({"even_half", std::move(even)});
    return layers;
}

}  // namespace render
