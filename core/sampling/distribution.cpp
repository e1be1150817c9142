#include "core/sampling/distribution.h"

#include <algorithm>
#include <cmath>

#include "core/math/constants.h"

namespace render {

Distribution1D::Distribution1D(std::vector<float> weights) : func_(std::move(weights)) {
    size_t n = func_.size();
    cdf_.assign(n + 1, 0.0);
    for (size_t i = 0; i < n; ++i) {
        float w = std::isfinite(func_[i]) ? std::max(0.0f, func_[i]) : 0.0f;
        func_[i] = w;
        cdf_[i + 1] = cdf_[i] + double(w);
    }
    double total = cdf_[n];
    integral_ = n > 0 ? float(total / double(n)) : 0.0f;
    if (total <= 0) {
        // All zero: sample uniformly so sampling stays well defined, but keep reporting the
        // true (zero) weights and integral so callers can detect a black distribution.
        for (size_t i = 0; i < n; ++i) cdf_[i + 1] = double(i + 1) / double(n);
    } else {
        for (size_t i = 1; i <= n; ++i) cdf_[i] /= total;
    }
}

size_t Distribution1D::sample_discrete(float u, float* probability, float* u_remapped) const {
    // Largest i with cdf_[i] <= u, among bins of non-zero probability.
    size_t n = func_.size();
    auto it = std::upper_bound(cdf_.begin(), cdf_.end(), double(u));
    size_t i = size_t(std::clamp<ptrdiff_t>((it - cdf_.begin()) - 1, 0, ptrdiff_t(n) - 1));
    while (i + 1 < n && cdf_[i + 1] == cdf_[i]) ++i;  // skip empty bins at ties
    double p = cdf_[i + 1] - cdf_[i];
    if (probability) *probability = float(p);
    if (u_remapped)
        *u_remapped = p > 0 ? std::min(float((u - cdf_[i]) / p), kOneMinusEpsilon) : 0.0f;
    return i;
}

float Distribution1D::discrete_probability(size_t i) const {
    return i < func_.size() ? float(cdf_[i + 1] - cdf_[i]) : 0.0f;
}

float Distribution1D::sample_continuous(float u, float* pdf, size_t* index) const {
    float remapped;
    float p;
    size_t i = sample_discrete(u, &p, &remapped);
    if (index) *index = i;
    if (pdf) *pdf = p * float(func_.size());
    return std::min((float(i) + remapped) / float(func_.size()), kOneMinusEpsilon);
}

float Distribution1D::pdf_continuous(float x) const {
    if (func_.empty() || !(x >= 0 && x < 1)) return 0.0f;
    size_t i = std::min(size_t(x * float(func_.size())), func_.size() - 1);
    return discrete_probability(i) * float(func_.size());
}

Distribution2D::Distribution2D(const std::vector<float>& weights, size_t width, size_t height) {
    conditional_.reserve(height);
    std::vector<float> row_sums(height);
    for (size_t y = 0; y < height; ++y) {
        std::vector<float> row(weights.begin() + y * width, weights.begin() + (y + 1) * width);
        double sum = 0;
        for (float w : row) sum += std::isfinite(w) ? std::max(0.0f, w) : 0.0f;
        row_sums[y] = float(sum);
        conditional_.emplace_back(std::move(row));
    }
    marginal_ = Distribution1D(std::move(row_sums));
}

Vec2 Distribution2D::sample(Vec2 u, float* pdf_a) const {
    float pdf_row, pdf_col;
    size_t row;
    float y = marginal_.sample_continuous(u.y, &pdf_row, &row);
    float x = conditional_[row].sample_continuous(u.x, &pdf_col);
    if (pdf_a) *pdf_a = pdf_row * pdf_col;
    return {x, y};
}

float Distribution2D::pdf_a(Vec2 p) const {
    if (conditional_.empty() || !(p.y >= 0 && p.y < 1)) return 0.0f;
    size_t row = std::min(size_t(p.y * float(conditional_.size())), conditional_.size() - 1);
    return marginal_.pdf_continuous(p.y) * conditional_[row].pdf_continuous(p.x);
}

}  // namespace render
