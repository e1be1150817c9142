#include "core/image/fixed_point_sums.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace render {

int64_t FixedPointSums::quantize(double brightness) {
    if (!(brightness > 0)) return 0;                                   // also NaN
    constexpr int64_t kMax = (int64_t(1) << (2 * kFractionBits)) - 1;  // kMaxValue on the grid
    if (brightness >= kMaxValue) return kMax;
    return std::min(int64_t(std::llround(std::ldexp(brightness, kFractionBits))), kMax);
}

void FixedPointSums::add_iteration(const std::vector<double>& rgb, uint64_t iteration) {
    const bool odd = iteration % 2 == 1;
    for (size_t p = 0; p < sum_.size(); ++p) {
        const int64_t v = quantize(rgb[3 * p] + rgb[3 * p + 1] + rgb[3 * p + 2]);
        sum_[p] += v;
        if (odd) odd_[p] += v;
    }
}

void FixedPointSums::add(const FixedPointSums& other) {
    for (size_t p = 0; p < sum_.size() && p < other.sum_.size(); ++p) {
        sum_[p] += other.sum_[p];
        odd_[p] += other.odd_[p];
    }
}

void FixedPointSums::add(size_t first, std::span<const int64_t> sum, std::span<const int64_t> odd) {
    if (first > sum_.size() || sum.size() > sum_.size() - first ||
        (!odd.empty() && odd.size() != sum.size()))
        throw std::invalid_argument("FixedPointSums::add: arrays past the frame's pixels");
    for (size_t i = 0; i < sum.size(); ++i) sum_[first + i] += sum[i];
    for (size_t i = 0; i < odd.size(); ++i) odd_[first + i] += odd[i];
}

}  // namespace render
