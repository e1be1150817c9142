#pragma once

// A chi-square goodness-of-fit test in the style of Mitsuba's ChiSquareTest: draw many samples
// from a sampling routine, histogram them, and compare against the expected counts obtained by
// numerically integrating (Gauss-Legendre, interior nodes only) the pdf that the routine claims
// over each histogram cell. Cells with
// small expected counts are pooled (each pooled group needs >= 5 expected samples). The null
// hypothesis "samples follow the pdf" is rejected when the p-value falls below the significance
// level, Sidak-corrected for the number of tests a suite runs:
//     alpha = 1 - (1 - 0.01)^(1 / test_count).
// Fixed seeds make every run identical; a wrong pdf or sampler fails with p ~ 0.

#include <functional>
#include <optional>
#include <string>

#include "core/math/vec.h"
#include "core/sampling/rng.h"

namespace render::testing {

struct ChiSquareResult {
    bool passed = false;
    double p_value = 0;
    double statistic = 0;
    int degrees_of_freedom = 0;
    double pdf_integral = 0;  // integral of the pdf over the domain, should be <= 1
    std::string message;      // the worst cells, for failure output
};

struct ChiSquareOptions {
    int resolution_x = 32;
    int resolution_y = 32;
    int sample_count = 1000000;
    int test_count = 1;  // tests in the suite, for the Sidak correction
    double significance = 0.01;
    uint64_t seed = 1;
};

// Domain [x0, x1] x [y0, y1]. `sample` draws one point (or nothing, when sampling fails) from
// two uniform numbers and an extra one for lobe selection; `pdf` is the claimed density w.r.t.
// dx dy.
struct Rect {
    double x0, x1, y0, y1;
};
ChiSquareResult chi_square_test_2d(const std::function<std::optional<Vec2>(Rng&)>& sample,
                                   const std::function<double(Vec2)>& pdf, Rect domain,
                                   const ChiSquareOptions& options);

// Unit directions, histogrammed over (phi, cos theta) so that every cell has the same solid
// angle; `pdf` is w.r.t. solid angle.
ChiSquareResult chi_square_test_sphere(const std::function<std::optional<Vec3>(Rng&)>& sample,
                                       const std::function<double(const Vec3&)>& pdf,
                                       const ChiSquareOptions& options);

// Regularised upper incomplete gamma Q(a, x); the chi-square survival function is
// Q(dof / 2, statistic / 2). Exposed for its own test.
double regularized_gamma_q(double a, double x);

}  // namespace render::testing
