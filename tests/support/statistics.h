#pragma once

// Mean and standard error of the mean of n independent estimates of one value: per-batch means
// of a render (batch means), per-iteration region means, the pixels of an image whose pixels
// all estimate the same value, or single Monte Carlo samples. With the sample variance
//     s^2 = sum_i (x_i - mean)^2 / (n - 1),
// the standard error of the mean is s / sqrt(n). Accumulated with Welford's update, which
// does not cancel catastrophically when the spread is small against the mean.

#include <cmath>
#include <vector>

namespace render::testing {

struct MeanEstimate {
    double mean = 0, standard_error = 0;
};

class MeanAccumulator {
  public:
    void add(double x) {
        ++n_;
        const double delta = x - mean_;
        mean_ += delta / double(n_);
        m2_ += delta * (x - mean_);
    }
    long count() const { return n_; }
    double mean() const { return mean_; }
    // 0 for fewer than two estimates (no spread to measure).
    double standard_error() const {
        return n_ > 1 ? std::sqrt(m2_ / double(n_ - 1) / double(n_)) : 0.0;
    }
    MeanEstimate estimate() const { return {mean(), standard_error()}; }

  private:
    long n_ = 0;
    double mean_ = 0, m2_ = 0;
};

// Batch means: the mean of the per-batch means and its standard error from their spread.
inline MeanEstimate batch_means(const std::vector<double>& means) {
    MeanAccumulator a;
    for (double m : means) a.add(m);
    return a.estimate();
}

}  // namespace render::testing
