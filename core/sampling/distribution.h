#pragma once

// Piecewise-constant distributions: 1-D over [0, 1) (also used discretely, e.g. to pick a light
// by power) and 2-D over [0, 1)^2 as a marginal over rows times conditionals (envmaps).

#include <cstddef>
#include <vector>

#include "core/math/vec.h"

namespace render {

class Distribution1D {
  public:
    Distribution1D() = default;
    // Non-finite or negative weights count as zero. If all are zero, sampling is uniform (so
    // it never fails on a black envmap row) while weight() and integral() still report zero.
    explicit Distribution1D(std::vector<float> weights);

    size_t size() const { return func_.size(); }
    float integral() const { return integral_; }  // sum(weights) / size()
    float weight(size_t i) const { return func_[i]; }

    // Discrete sampling: index i with probability discrete_probability(i).
    size_t sample_discrete(float u, float* probability = nullptr,
                           float* u_remapped = nullptr) const;
    float discrete_probability(size_t i) const;

    // Continuous sampling on [0, 1): returns x with density pdf(x) = weight(i) / integral().
    float sample_continuous(float u, float* pdf = nullptr, size_t* index = nullptr) const;
    float pdf_continuous(float x) const;

  private:
    std::vector<float> func_;
    std::vector<double> cdf_;  // size + 1 entries, cdf_[0] = 0, cdf_.back() = 1
    float integral_ = 0;
};

class Distribution2D {
  public:
    Distribution2D() = default;
    // weights[row * width + col]; rows are along v (y), columns along u (x).
    Distribution2D(const std::vector<float>& weights, size_t width, size_t height);

    // Point in [0,1)^2 with density pdf_a(p) w.r.t. the unit square's area.
    Vec2 sample(Vec2 u, float* pdf_a = nullptr) const;
    float pdf_a(Vec2 p) const;

  private:
    std::vector<Distribution1D> conditional_;  // one per row
    Distribution1D marginal_;                  // over rows
};

}  // namespace render
