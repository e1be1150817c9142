#include "tests/support/chi_square.h"

#include <gtest/gtest.h>

#include <cmath>
#include <utility>

#include "core/sampling/warp.h"

namespace render::testing {
namespace {

TEST(ChiSquare, GammaQMatchesKnownValues) {
    // Chi-square survival with 2 dof is exp(-x/2); with 1 dof it is erfc(sqrt(x/2)).
    EXPECT_NEAR(regularized_gamma_q(1.0, 1.5), std::exp(-1.5), 1e-12);
    EXPECT_NEAR(regularized_gamma_q(0.5, 2.0), std::erfc(std::sqrt(2.0)), 1e-12);
    // For integer a, Q(a, x) is the Poisson CDF: exp(-x) sum_{k<a} x^k / k!.
    for (auto [a, x] : {std::pair{50, 50.0}, std::pair{10, 3.0}, std::pair{4, 20.0}}) {
        double term = std::exp(-x), poisson = 0;
        for (int k = 0; k < a; ++k) poisson += term, term *= x / (k + 1);
        EXPECT_NEAR(regularized_gamma_q(a, x), poisson, 1e-12 + 1e-10 * poisson);
    }
}

TEST(ChiSquare, RejectsAWrongPdf) {
    // Cosine-weighted samples tested against the uniform hemisphere pdf must fail.
    ChiSquareOptions options;
    options.sample_count = 200000;
    auto sample = [](Rng& rng) -> std::optional<Vec3> {
        return warp::square_to_cosine_hemisphere(rng.next_2d());
    };
    auto wrong_pdf = [](const Vec3& w) {
        return double(warp::square_to_uniform_hemisphere_pdf(w));
    };
    ChiSquareResult result = chi_square_test_sphere(sample, wrong_pdf, options);
    EXPECT_FALSE(result.passed) << result.message;
    EXPECT_LT(result.p_value, 1e-6);
}

}  // namespace
}  // namespace render::testing
