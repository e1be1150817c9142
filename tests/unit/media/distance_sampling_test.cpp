// Distance sampling in a homogeneous medium with spectral MIS (core/media/homogeneous_medium.h):
// chi-square tests of the sampled distances and pass events (tests/support/chi_square.h),
// unbiasedness and bounds of the weights stated in standard errors, the closed forms of the
// densities, and degenerate coefficients. Fixed seeds throughout.

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <memory>
#include <optional>
#include <utility>
#include <vector>

#include "core/math/constants.h"
#include "core/math/ray.h"
#include "core/media/homogeneous_medium.h"
#include "core/media/isotropic_phase.h"
#include "tests/support/chi_square.h"
#include "tests/support/statistics.h"

namespace render::testing {
namespace {

// The chi-square checks of this file, Sidak-corrected together (tests/support/chi_square.h).
ChiSquareFamily family;

// Deviations of a sample mean from its expectation, in standard errors.
constexpr double kStandardErrors = 5.0;

const Ray kRay(Vec3(0.3f, -0.2f, 1.0f), normalize(Vec3(1, 2, -0.5f)));

std::shared_ptr<const PhaseFunction> isotropic() {
    return std::make_shared<IsotropicPhase>();
}

// Chi-square of sample()'s outcome: the scattering distance in (0, t_max), histogrammed in 64
// cells, and the pass-through event as a 65th cell [t_max, t_max * 65 / 64] of density
// P(pass) / width (the sample lands at its centre); a dummy second coordinate (one cell).
ChiSquareResult distance_chi_square(const Medium& medium, float t_max,
                                    const std::function<double(double)>& pdf_scatter_l,
                                    double probability_pass, uint64_t seed) {
    const int cells = 64;
    const double width = double(t_max) / cells;
    auto sample = [&](Rng& rng) -> std::optional<Vec2> {
        MediumSample s = medium.sample(kRay, t_max, rng);
        return Vec2(s.scattered ? s.t : float(t_max + 0.5 * width), 0.5f);
    };
    auto pdf = [&](Vec2 p) { return p.x < t_max ? pdf_scatter_l(p.x) : probability_pass / width; };
    ChiSquareOptions o;
    o.seed = seed;
    o.resolution_x = cells + 1;
    o.resolution_y = 1;
    return chi_square_test_2d(family, sample, pdf, Rect{0.0, t_max + width, 0.0, 1.0}, o);
}

// (a) Grey coefficients: the distance density is sigma_t exp(-sigma_t t) on (0, t_max) and
// the pass probability exp(-sigma_t t_max); every weight is the albedo (scatter) or 1 (pass).
CHI_SQUARE_TEST(family, MediaDistance, GreyMatchesExponential, 1) {
    const double sigma_t = 2.0, sigma_s = 1.5;
    const float t_max = 1.3f;
    HomogeneousMedium medium(Rgb(float(sigma_t - sigma_s)), Rgb(float(sigma_s)), isotropic());
    ChiSquareResult r = distance_chi_square(
        medium, t_max, [&](double t) { return sigma_t * std::exp(-sigma_t * t); },
        std::exp(-sigma_t * t_max), 501);
    EXPECT_TRUE(r.passed) << r.message;
    EXPECT_NEAR(r.pdf_integral, 1.0, 1e-4) << r.message;

    Rng rng(StreamKey{502, 0, 1, 0});
    const int n = 1000000;
    int passed = 0;
    for (int i = 0; i < n; ++i) {
        MediumSample s = medium.sample(kRay, t_max, rng);
        if (s.scattered) {
            ASSERT_GE(s.t, 0.0f);
            ASSERT_LT(s.t, t_max);
            for (int c = 0; c < 3; ++c) ASSERT_NEAR(s.weight[c], sigma_s / sigma_t, 1e-5);
        } else {
            ++passed;
            ASSERT_EQ(s.t, t_max);
            for (int c = 0; c < 3; ++c) ASSERT_NEAR(s.weight[c], 1.0, 1e-5);
        }
    }
    const double p = std::exp(-sigma_t * t_max), se = std::sqrt(p * (1 - p) / n);
    EXPECT_NEAR(double(passed) / n, p, kStandardErrors * se);
}

// (b) Chromatic coefficients and spectral MIS: per channel, E[weight 1{scattered in [a, b]}]
// equals the integral of sigma_s exp(-sigma_t t) over [a, b], and E[weight 1{passed}] the
// transmittance to t_max; weights stay within the bounds medium.h states.
TEST(MediaDistance, ChromaticSpectralMisIsUnbiasedAndBounded) {
    const Rgb sigma_t(12.02f, 22.0f, 22.0f), sigma_s(12.0f, 20.0f, 20.0f);
    const float t_max = 0.25f;
    HomogeneousMedium medium(sigma_t - sigma_s, sigma_s, isotropic());
    const std::vector<std::pair<double, double>> ranges = {
        {0.0, 0.01}, {0.01, 0.05}, {0.05, 0.1}, {0.1, 0.25}};
    const int n = 2000000;
    const int slots = int(ranges.size()) + 1;  // the last one is the pass event
    // E[weight_c 1{slot}] per slot and channel: every sample adds to every slot (0 to the
    // slots it does not fall in).
    std::vector<MeanAccumulator> estimate(3 * slots);
    Rng rng(StreamKey{511, 0, 1, 0});
    for (int i = 0; i < n; ++i) {
        MediumSample s = medium.sample(kRay, t_max, rng);
        ASSERT_TRUE(s.weight.is_finite());
        int slot = -1;
        if (s.scattered) {
            ASSERT_GE(s.t, 0.0f);
            ASSERT_LT(s.t, t_max);
            for (int k = 0; k < int(ranges.size()); ++k)
                if (s.t >= ranges[k].first && s.t < ranges[k].second) slot = k;
            for (int c = 0; c < 3; ++c)
                ASSERT_LE(s.weight[c], 3.0f * sigma_s[c] / sigma_t[c] * (1 + 1e-5f)) << c;
        } else {
            ASSERT_EQ(s.t, t_max);
            slot = slots - 1;
            for (int c = 0; c < 3; ++c) ASSERT_LE(s.weight[c], 3.0f * (1 + 1e-5f)) << c;
        }
        ASSERT_GE(slot, 0) << s.t;
        for (int c = 0; c < 3; ++c) {
            ASSERT_GE(s.weight[c], 0.0f);
            for (int k = 0; k < slots; ++k) estimate[3 * k + c].add(k == slot ? s.weight[c] : 0.0);
        }
    }
    for (int slot = 0; slot < slots; ++slot)
        for (int c = 0; c < 3; ++c) {
            const double st = sigma_t[c], ss = sigma_s[c];
            double expected;
            if (slot < slots - 1) {
                auto [a, b] = ranges[slot];
                expected = ss / st * (std::exp(-st * a) - std::exp(-st * b));
            } else {
                expected = std::exp(-st * t_max);
            }
            const double mean = estimate[3 * slot + c].mean(),
                         se = estimate[3 * slot + c].standard_error();
            EXPECT_NEAR(mean, expected, kStandardErrors * se)
                << "slot " << slot << ", channel " << c << ", standard error " << se;
        }
}

// Independent closed forms of the spectral-MIS densities.
double mis_pdf_scatter_l(const Rgb& sigma_t, double t) {
    double sum = 0;
    for (int c = 0; c < 3; ++c) sum += sigma_t[c] * std::exp(-double(sigma_t[c]) * t);
    return sum / 3;
}
double mis_probability_pass(const Rgb& sigma_t, double t) {
    double sum = 0;
    for (int c = 0; c < 3; ++c) sum += std::exp(-double(sigma_t[c]) * t);
    return sum / 3;
}

// (c) pdf_scatter_l and probability_pass describe sample()'s distribution (what bidirectional
// MIS relies on), and equal the closed forms.
// One check per case.
CHI_SQUARE_TEST(family, MediaDistance, PdfScatterAndProbabilityPassMatchSamples, 2) {
    struct Case {
        Rgb sigma_t, sigma_s;
        float t_max;
    };
    const Case cases[] = {{Rgb(12.02f, 22.0f, 22.0f), Rgb(12.0f, 20.0f, 20.0f), 0.25f},
                          {Rgb(0.0f, 3.0f, 8.0f), Rgb(0.0f, 2.0f, 7.5f), 0.6f}};
    uint64_t seed = 520;
    for (const Case& k : cases) {
        SCOPED_TRACE(::testing::Message() << "sigma_t = " << k.sigma_t);
        HomogeneousMedium medium(k.sigma_t - k.sigma_s, k.sigma_s, isotropic());
        ChiSquareResult r = distance_chi_square(
            medium, k.t_max, [&](double t) { return medium.pdf_scatter_l(kRay, float(t)); },
            medium.probability_pass(kRay, k.t_max), ++seed);
        EXPECT_TRUE(r.passed) << r.message;
        EXPECT_NEAR(r.pdf_integral, 1.0, 1e-4) << r.message;
        for (double t : {0.0, 0.001, 0.01, 0.1, 0.3, 1.0, 10.0}) {
            double pdf = mis_pdf_scatter_l(k.sigma_t, t), pass = mis_probability_pass(k.sigma_t, t);
            EXPECT_NEAR(medium.pdf_scatter_l(kRay, float(t)), pdf, 1e-5 * pdf + 1e-30) << t;
            EXPECT_NEAR(medium.probability_pass(kRay, float(t)), pass, 1e-5 * pass + 1e-30) << t;
        }
        EXPECT_EQ(medium.pdf_scatter_l(kRay, kInfinity), 0.0f);
        EXPECT_NEAR(medium.probability_pass(kRay, kInfinity), k.sigma_t[0] == 0 ? 1.0 / 3.0 : 0.0,
                    1e-7);
    }
}

// (d) Degenerate coefficients and infinite segments: no NaN or infinity, and the weights are
// still bounded.
TEST(MediaDistance, EdgeCasesStayFinite) {
    struct Case {
        const char* name;
        Rgb sigma_t, sigma_s;
    };
    const Case cases[] = {
        {"one channel zero", Rgb(0.0f, 5.0f, 5.0f), Rgb(0.0f, 4.0f, 4.0f)},
        {"all zero", Rgb(0.0f), Rgb(0.0f)},
        {"huge", Rgb(1e6f), Rgb(0.5e6f)},
        {"tiny", Rgb(1e-9f), Rgb(0.5e-9f)},
        {"huge, tiny and zero", Rgb(1e6f, 1e-9f, 0.0f), Rgb(0.9e6f, 1e-9f, 0.0f)},
        {"huge and ordinary", Rgb(1e6f, 1.0f, 2.0f), Rgb(1e6f, 0.5f, 1.0f)},
    };
    for (const Case& k : cases)
        for (float t_max : {1.0f, 1e-3f, kInfinity}) {
            SCOPED_TRACE(::testing::Message() << k.name << ", t_max = " << t_max);
            HomogeneousMedium medium(k.sigma_t - k.sigma_s, k.sigma_s, isotropic());
            Rng rng(StreamKey{531, 0, 1, 0});
            int passes = 0;
            const int n = 100000;
            for (int i = 0; i < n; ++i) {
                MediumSample s = medium.sample(kRay, t_max, rng);
                ASSERT_TRUE(s.weight.is_finite()) << s.weight << " at t = " << s.t;
                ASSERT_FALSE(std::isnan(s.t));
                if (s.scattered) {
                    ASSERT_TRUE(std::isfinite(s.t));
                    ASSERT_GE(s.t, 0.0f);
                    ASSERT_LT(s.t, t_max);
                    for (int c = 0; c < 3; ++c) {
                        float albedo = k.sigma_t[c] > 0 ? k.sigma_s[c] / k.sigma_t[c] : 0.0f;
                        ASSERT_LE(s.weight[c], 3.0f * albedo * (1 + 1e-5f)) << c;
                    }
                    float pdf = medium.pdf_scatter_l(kRay, s.t);
                    ASSERT_TRUE(std::isfinite(pdf) && pdf > 0) << pdf;
                } else {
                    ++passes;
                    ASSERT_EQ(s.t, t_max);
                    for (int c = 0; c < 3; ++c) ASSERT_LE(s.weight[c], 3.0f * (1 + 1e-5f)) << c;
                }
                ASSERT_GE(s.weight.r, 0.0f);
                ASSERT_GE(s.weight.g, 0.0f);
                ASSERT_GE(s.weight.b, 0.0f);
            }
            Rng unused(StreamKey{0, 0, 1, 0});
            Rgb tr = medium.transmittance(kRay, t_max, unused);
            EXPECT_TRUE(tr.is_finite()) << tr;
            EXPECT_TRUE(std::isfinite(medium.probability_pass(kRay, t_max)));
            EXPECT_TRUE(std::isfinite(medium.pdf_scatter_l(kRay, t_max)));
            if (k.sigma_t.is_black()) {
                // A vacuum: always passes with weight exactly 1.
                EXPECT_EQ(passes, n);
                EXPECT_EQ(tr, Rgb(1.0f));
                Rng again(StreamKey{532, 0, 1, 0});
                MediumSample s = medium.sample(kRay, t_max, again);
                EXPECT_EQ(s.weight, Rgb(1.0f));
            }
            if (std::isinf(t_max) && k.sigma_t[0] > 0 && k.sigma_t[1] > 0 && k.sigma_t[2] > 0) {
                EXPECT_EQ(passes, 0);  // an infinite medium always scatters
            }
            if (std::isinf(t_max) && k.sigma_t[0] == 0 && k.sigma_t[1] > 0 && k.sigma_t[2] > 0) {
                // Only the zero channel passes, with weight 3 (its probability is 1/3).
                Rng again(StreamKey{533, 0, 1, 0});
                for (int i = 0; i < 1000; ++i) {
                    MediumSample s = medium.sample(kRay, t_max, again);
                    if (!s.scattered) {
                        EXPECT_NEAR(s.weight.r, 3.0f, 1e-5f);
                        EXPECT_EQ(s.weight.g, 0.0f);
                        EXPECT_EQ(s.weight.b, 0.0f);
                    }
                }
            }
        }
    HomogeneousMedium huge(Rgb(0.5e6f), Rgb(0.5e6f), isotropic());
    EXPECT_EQ(huge.transmittance(kInfinity), Rgb(0.0f));
    EXPECT_EQ(huge.transmittance(0.0f), Rgb(1.0f));
}

}  // namespace
}  // namespace render::testing
