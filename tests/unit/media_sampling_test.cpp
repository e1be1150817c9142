// The sampling routines of participating media against their densities: phase functions
// (core/media/isotropic_phase.h, henyey_greenstein.h), distance sampling with spectral MIS
// (core/media/homogeneous_medium.h) and equi-angular sampling (core/sampling/equiangular.h).
// Chi-square tests (tests/support/chi_square.h, Sidak-corrected for this file), numerical
// normalisation checks, and moment tests stated in standard errors. Fixed seeds throughout.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <memory>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "core/math/ray.h"
#include "core/media/henyey_greenstein.h"
#include "core/media/homogeneous_medium.h"
#include "core/media/isotropic_phase.h"
#include "core/sampling/equiangular.h"
#include "tests/support/chi_square.h"

namespace render::testing {
namespace {

// Number of chi-square tests in this file, for the Sidak correction:
//   phase functions: 1 isotropic + 6 g x 3 wo (whole sphere) + 2 g x 2 wo (lobe caps) = 23
//   distance sampling: grey, chromatic, chromatic with a zero channel = 3
//   equi-angular: 4 configurations in t and in the angle chart + 5 guard cases = 13
constexpr int kChiSquareTests = 39;

// Deviations of a sample mean from its expectation, in standard errors.
constexpr double kStandardErrors = 5.0;

ChiSquareOptions options(uint64_t seed) {
    ChiSquareOptions o;
    o.test_count = kChiSquareTests;
    o.seed = seed;
    return o;
}

double sidak_alpha() {
    return 1.0 - std::pow(1.0 - 0.01, 1.0 / kChiSquareTests);
}

// An orthonormal frame around `axis` built by Gram-Schmidt, independently of core/math/frame.h
// (which the phase functions use), so that a frame bug cannot cancel out.
struct TestFrame {
    Vec3 s, t, n;
    explicit TestFrame(const Vec3& axis) : n(normalize(axis)) {
        Vec3 helper = std::abs(n.x) < 0.6f ? Vec3(1, 0, 0) : Vec3(0, 1, 0);
        s = normalize(helper - n * dot(helper, n));
        t = cross(n, s);
    }
    Vec3 to_world(double phi, double z) const {
        double r = std::sqrt(std::max(0.0, 1.0 - z * z));
        return s * float(r * std::cos(phi)) + t * float(r * std::sin(phi)) + n * float(z);
    }
};

// ------------------------------------------------------------------------------------------
// Phase functions

const Vec3 kWoTilted = normalize(Vec3(0.3f, -0.5f, 0.8f));
const Vec3 kWoLow = normalize(Vec3(-0.7f, 0.1f, -0.2f));
const Vec3 kWoEquator = Vec3(1, 0, 0);
const float kHgG[] = {-0.9f, -0.3f, 0.0f, 0.01f, 0.5f, 0.95f};

// Independent closed form of Henyey-Greenstein, in double: cos_theta is the angle between
// the propagation directions, dot(-wo, wi).
double hg_reference(double g, double cos_theta) {
    double denom = 1.0 + g * g - 2.0 * g * cos_theta;
    return (1.0 - g * g) / (4.0 * M_PI * denom * std::sqrt(denom));
}

// Integral of p(wo, .) over the sphere, midpoint rule in (phi, z) of a frame whose pole is
// the propagation direction -wo, where forward and backward lobes sit at the poles; the z grid
// is fine enough for g = 0.95 (lobe width ~ (1 - g)^2 / (2 g) ~ 1e-3 in z).
double integrate_phase(const PhaseFunction& phase, const Vec3& wo) {
    TestFrame frame(-wo);
    const int n_phi = 16, n_z = 100000;
    double sum = 0;
    for (int i = 0; i < n_phi; ++i) {
        double phi = 2.0 * M_PI * (i + 0.5) / n_phi;
        for (int j = 0; j < n_z; ++j) {
            double z = -1.0 + 2.0 * (j + 0.5) / n_z;
            sum += phase.p(wo, frame.to_world(phi, z));
        }
    }
    return sum * (2.0 * M_PI / n_phi) * (2.0 / n_z);
}

void expect_passes(const ChiSquareResult& r) {
    EXPECT_TRUE(r.passed) << r.message;
}

// Every sample is a unit direction whose reported pdf equals p(wo, wi) and is positive.
void expect_well_formed(const PhaseFunction& phase, const Vec3& wo) {
    Rng rng(StreamKey{11, 0, 1, 0});
    const Vec2 corners[] = {{0, 0},
                            {kOneMinusEpsilon, 0},
                            {0, kOneMinusEpsilon},
                            {kOneMinusEpsilon, kOneMinusEpsilon},
                            {0.5f, 0.5f}};
    for (int i = 0; i < 20000 + 5; ++i) {
        Vec2 u = i < 5 ? corners[i] : rng.next_2d();
        PhaseSample s = phase.sample(wo, u);
        ASSERT_TRUE(is_finite(s.wi)) << "u = " << u.x << ", " << u.y;
        ASSERT_NEAR(length(s.wi), 1.0f, 1e-5f);
        ASSERT_TRUE(std::isfinite(s.pdf_w) && s.pdf_w > 0) << s.pdf_w;
        float p = phase.p(wo, s.wi);
        ASSERT_NEAR(s.pdf_w, p, 2e-3f * p) << "u = " << u.x << ", " << u.y;
    }
}

// The sampled directions against p(wo, .) over the whole sphere (world coordinates).
ChiSquareResult phase_chi_square_sphere(const PhaseFunction& phase, const Vec3& wo, uint64_t seed) {
    return chi_square_test_sphere(
        [&](Rng& rng) -> std::optional<Vec3> { return phase.sample(wo, rng.next_2d()).wi; },
        [&](const Vec3& wi) { return double(phase.p(wo, wi)); }, options(seed));
}

// The sampled directions against p(wo, .) in the cap z >= z_min of a frame around `axis`
// (the lobe's direction), which resolves narrow lobes that the whole-sphere histogram cannot.
// Chart (phi, z), d omega = d phi dz; samples outside the cap are dropped and the expected
// counts integrate over the cap only, so the cap's total mass is tested as well.
ChiSquareResult phase_chi_square_cap(const PhaseFunction& phase, const Vec3& wo, const Vec3& axis,
                                     double z_min, uint64_t seed) {
    TestFrame frame(axis);
    auto sample = [&](Rng& rng) -> std::optional<Vec2> {
        Vec3 wi = phase.sample(wo, rng.next_2d()).wi;
        float z = dot(wi, frame.n);
        if (z < z_min) return std::nullopt;
        float phi = std::atan2(dot(wi, frame.t), dot(wi, frame.s));
        if (phi < 0) phi += 2.0f * kPi;
        return Vec2(phi, z);
    };
    auto pdf = [&](Vec2 c) { return double(phase.p(wo, frame.to_world(c.x, c.y))); };
    return chi_square_test_2d(sample, pdf, Rect{0.0, 2.0 * M_PI, z_min, 1.0}, options(seed));
}

TEST(MediaPhase, Isotropic) {
    IsotropicPhase phase;
    expect_well_formed(phase, kWoTilted);
    expect_passes(phase_chi_square_sphere(phase, kWoTilted, 101));
    EXPECT_NEAR(integrate_phase(phase, kWoTilted), 1.0, 1e-4);
    EXPECT_NEAR(phase.p(kWoTilted, kWoLow), 1.0 / (4.0 * M_PI), 1e-7);
}

TEST(MediaPhase, HenyeyGreensteinChiSquareWholeSphere) {
    uint64_t seed = 200;
    for (float g : kHgG) {
        HenyeyGreenstein phase(g);
        for (const Vec3& wo : {kWoTilted, kWoLow, kWoEquator}) {
            SCOPED_TRACE(::testing::Message() << "g = " << g << ", wo = " << wo);
            expect_well_formed(phase, wo);
            ChiSquareResult r = phase_chi_square_sphere(phase, wo, ++seed);
            expect_passes(r);
            // The harness's cell integration resolves the lobe too (a check on the test).
            EXPECT_NEAR(r.pdf_integral, 1.0, 2e-3) << r.message;
        }
    }
}

TEST(MediaPhase, HenyeyGreensteinChiSquareLobe) {
    // (g, cap): the cap around the lobe holds ~80 % (g = -0.9, z >= 0.8) and ~91 %
    // (g = 0.95, z >= 0.9) of the mass; the lobe is at -wo for g > 0 and at wo for g < 0.
    // wo on the pole exercises the frame construction's special case.
    uint64_t seed = 300;
    for (auto [g, z_min] : {std::pair{-0.9f, 0.8}, {0.95f, 0.9}}) {
        HenyeyGreenstein phase(g);
        for (const Vec3& wo : {kWoTilted, Vec3(0, 0, 1)}) {
            SCOPED_TRACE(::testing::Message() << "g = " << g << ", wo = " << wo);
            expect_well_formed(phase, wo);
            Vec3 axis = g > 0 ? -wo : wo;
            expect_passes(phase_chi_square_cap(phase, wo, axis, z_min, ++seed));
        }
    }
}

TEST(MediaPhase, HenyeyGreensteinMatchesClosedFormAndIntegratesToOne) {
    Rng rng(StreamKey{21, 0, 1, 0});
    for (float g : kHgG) {
        SCOPED_TRACE(g);
        HenyeyGreenstein phase(g);
        EXPECT_FLOAT_EQ(phase.g(), g);
        for (const Vec3& wo : {kWoTilted, kWoLow, Vec3(0, 0, -1)})
            EXPECT_NEAR(integrate_phase(phase, wo), 1.0, 1e-4) << wo;
        for (int i = 0; i < 1000; ++i) {
            Vec3 wo =
                normalize(Vec3(rng.next_1d() - 0.5f, rng.next_1d() - 0.5f, rng.next_1d() - 0.5f));
            Vec3 wi =
                normalize(Vec3(rng.next_1d() - 0.5f, rng.next_1d() - 0.5f, rng.next_1d() - 0.5f));
            double expected = hg_reference(g, -double(dot(wo, wi)));
            ASSERT_NEAR(phase.p(wo, wi), expected, 1e-3 * expected + 1e-6) << wo << " " << wi;
        }
    }
}

TEST(MediaPhase, Reciprocity) {
    Rng rng(StreamKey{22, 0, 1, 0});
    for (float g : kHgG) {
        SCOPED_TRACE(g);
        HenyeyGreenstein phase(g);
        for (int i = 0; i < 10000; ++i) {
            Vec3 a =
                normalize(Vec3(rng.next_1d() - 0.5f, rng.next_1d() - 0.5f, rng.next_1d() - 0.5f));
            Vec3 b =
                normalize(Vec3(rng.next_1d() - 0.5f, rng.next_1d() - 0.5f, rng.next_1d() - 0.5f));
            float pab = phase.p(a, b), pba = phase.p(b, a);
            ASSERT_NEAR(pab, pba, 1e-5f * pab) << a << " " << b;
        }
    }
    IsotropicPhase iso;
    EXPECT_EQ(iso.p(kWoTilted, kWoLow), iso.p(kWoLow, kWoTilted));
}

// The mean cosine between the propagation directions, dot(-wo, wi), equals g.
TEST(MediaPhase, HenyeyGreensteinMeanCosineIsG) {
    const int n = 1000000;
    uint64_t seed = 400;
    for (float g : kHgG) {
        HenyeyGreenstein phase(g);
        for (const Vec3& wo : {kWoTilted, Vec3(0, 0, 1)}) {
            SCOPED_TRACE(::testing::Message() << "g = " << g << ", wo = " << wo);
            Rng rng(StreamKey{++seed, 0, 1, 0});
            double sum = 0, sum2 = 0;
            for (int i = 0; i < n; ++i) {
                double c = dot(-wo, phase.sample(wo, rng.next_2d()).wi);
                sum += c;
                sum2 += c * c;
            }
            double mean = sum / n, se = std::sqrt((sum2 / n - mean * mean) / n);
            EXPECT_NEAR(mean, g, kStandardErrors * se) << "standard error " << se;
        }
    }
}

// The sign convention of phase.h: both directions point away from the scattering point, so
// forward scattering (g > 0) continues along -wo.
TEST(MediaPhase, ForwardScatteringContinuesAlongMinusWo) {
    for (float g : {0.5f, 0.95f}) {
        SCOPED_TRACE(g);
        HenyeyGreenstein phase(g);
        const Vec3 wo = kWoTilted;
        EXPECT_GT(phase.p(wo, -wo), 10.0f * phase.p(wo, wo));
        Rng rng(StreamKey{23, 0, 1, 0});
        int forward = 0;
        const int n = 100000;
        for (int i = 0; i < n; ++i)
            if (dot(phase.sample(wo, rng.next_2d()).wi, -wo) > 0) ++forward;
        // P(cos theta > 0) = 0.75 for g = 0.5 and 0.97 for g = 0.95.
        EXPECT_GT(forward, (g > 0.9f ? 0.95 : 0.7) * n);
    }
    HenyeyGreenstein backward(-0.9f);
    EXPECT_GT(backward.p(kWoTilted, kWoTilted), 10.0f * backward.p(kWoTilted, -kWoTilted));
}

// ------------------------------------------------------------------------------------------
// Distance sampling in a homogeneous medium

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
    ChiSquareOptions o = options(seed);
    o.resolution_x = cells + 1;
    o.resolution_y = 1;
    return chi_square_test_2d(sample, pdf, Rect{0.0, t_max + width, 0.0, 1.0}, o);
}

// (a) Grey coefficients: the distance density is sigma_t exp(-sigma_t t) on (0, t_max) and
// the pass probability exp(-sigma_t t_max); every weight is the albedo (scatter) or 1 (pass).
TEST(MediaDistance, GreyMatchesExponential) {
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
    std::vector<double> sum(3 * slots, 0.0), sum2(3 * slots, 0.0);
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
            sum[3 * slot + c] += s.weight[c];
            sum2[3 * slot + c] += double(s.weight[c]) * s.weight[c];
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
            double mean = sum[3 * slot + c] / n;
            double se = std::sqrt(std::max(0.0, sum2[3 * slot + c] / n - mean * mean) / n);
            EXPECT_NEAR(mean, expected, kStandardErrors * se)
                << "slot " << slot << ", channel " << c << ", standard error " << se;
        }
}

// Independent closed forms of the spectral-MIS densities.
double mis_pdf_scatter(const Rgb& sigma_t, double t) {
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
TEST(MediaDistance, PdfScatterAndProbabilityPassMatchSamples) {
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
            double pdf = mis_pdf_scatter(k.sigma_t, t), pass = mis_probability_pass(k.sigma_t, t);
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

// ------------------------------------------------------------------------------------------
// Equi-angular sampling

// Integral of f over [a, b]: composite 3-point Gauss-Legendre on pieces graded geometrically
// toward `peak` (pieces [peak + h 2^k, peak + h 2^(k+1)] on both sides), so that a spike of
// width ~h is resolved however wide the range.
double integrate_graded(const std::function<double(double)>& f, double a, double b,
                        std::optional<double> peak = std::nullopt, double h = 0) {
    std::vector<double> points = {a, b};
    if (peak && h > 0) {
        if (*peak > a && *peak < b) points.push_back(*peak);
        for (double d = h; d < 2.0 * (b - a) + std::abs(*peak - a) + std::abs(*peak - b); d *= 2)
            for (double p : {*peak - d, *peak + d})
                if (p > a && p < b) points.push_back(p);
    }
    std::sort(points.begin(), points.end());
    const double nodes[3] = {-std::sqrt(0.6), 0.0, std::sqrt(0.6)};
    const double weights[3] = {5.0 / 9.0, 8.0 / 9.0, 5.0 / 9.0};
    double sum = 0;
    for (size_t i = 0; i + 1 < points.size(); ++i) {
        const int pieces = 16;
        double x0 = points[i], hx = (points[i + 1] - points[i]) / pieces;
        for (int j = 0; j < pieces; ++j) {
            double mid = x0 + (j + 0.5) * hx;
            for (int q = 0; q < 3; ++q) {
                double v = f(mid + 0.5 * hx * nodes[q]);
                sum += std::isfinite(v) ? 0.5 * hx * weights[q] * v : 0.0;
            }
        }
    }
    return sum;
}

// A one-dimensional chi-square test on [x0, x1] with `cells` cells, expected counts from
// integrate_graded (so spikes are integrated correctly), pooling as tests/support does.
ChiSquareResult chi_square_1d(const std::function<double(Rng&)>& sample,
                              const std::function<double(double)>& pdf, double x0, double x1,
                              int cells, uint64_t seed, std::optional<double> peak = std::nullopt,
                              double h = 0, int sample_count = 1000000) {
    std::vector<double> observed(cells, 0.0), expected(cells, 0.0);
    Rng rng(StreamKey{seed, 0, 1, 0});
    ChiSquareResult result;
    for (int i = 0; i < sample_count; ++i) {
        double x = sample(rng);
        if (!(x >= x0 && x <= x1)) {
            result.message = "sample " + std::to_string(x) + " outside the domain";
            return result;
        }
        observed[std::clamp(int((x - x0) / (x1 - x0) * cells), 0, cells - 1)] += 1;
    }
    const double w = (x1 - x0) / cells;
    for (int c = 0; c < cells; ++c) {
        double integral = integrate_graded(pdf, x0 + c * w, x0 + (c + 1) * w, peak, h);
        result.pdf_integral += integral;
        expected[c] = integral * sample_count;
    }
    std::vector<int> order(cells);
    for (int c = 0; c < cells; ++c) order[c] = c;
    std::sort(order.begin(), order.end(), [&](int a, int b) { return expected[a] < expected[b]; });
    double pooled_obs = 0, pooled_exp = 0, stat = 0;
    int groups = 0;
    std::ostringstream worst;
    double worst_contribution = -1;
    for (int c : order) {
        if (expected[c] == 0 && observed[c] > 0) {
            result.message = "cell " + std::to_string(c) + " has samples but no density";
            return result;
        }
        pooled_obs += observed[c];
        pooled_exp += expected[c];
        if (pooled_exp < 5.0) continue;
        double contribution = (pooled_obs - pooled_exp) * (pooled_obs - pooled_exp) / pooled_exp;
        if (contribution > worst_contribution) {
            worst_contribution = contribution;
            worst.str("");
            worst << "cell " << c << ": observed " << pooled_obs << ", expected " << pooled_exp;
        }
        stat += contribution;
        ++groups;
        pooled_obs = pooled_exp = 0;
    }
    if (pooled_exp > 0) {
        stat += (pooled_obs - pooled_exp) * (pooled_obs - pooled_exp) / pooled_exp;
        ++groups;
    }
    result.statistic = stat;
    result.degrees_of_freedom = std::max(1, groups - 1);
    result.p_value = regularized_gamma_q(0.5 * result.degrees_of_freedom, 0.5 * stat);
    result.passed = result.p_value >= sidak_alpha();
    std::ostringstream msg;
    msg << "chi2 = " << stat << ", dof = " << result.degrees_of_freedom
        << ", p = " << result.p_value << " (alpha = " << sidak_alpha()
        << "), pdf integral = " << result.pdf_integral << "; worst " << worst.str();
    result.message = msg.str();
    return result;
}

// A ray in general position and a light placed at ray distance `delta` of the foot point and
// perpendicular distance `distance` from the ray's line.
struct EquiAngularCase {
    const char* name;
    double delta, distance;
    float t0, t1;
};

const Vec3 kOrigin(0.3f, -1.0f, 2.0f);
const Vec3 kDirection = normalize(Vec3(1.0f, 2.0f, -0.5f));

Vec3 light_position(const EquiAngularCase& k) {
    Vec3 perpendicular = normalize(cross(kDirection, Vec3(0, 0, 1)));
    return kOrigin + kDirection * float(k.delta) + perpendicular * float(k.distance);
}

// The test's own ray distance of the foot point and distance of the light from the ray's line
// (double), from the light position actually used.
std::pair<double, double> foot_and_distance(const Vec3& light) {
    double lx = double(light.x) - kOrigin.x, ly = double(light.y) - kOrigin.y,
           lz = double(light.z) - kOrigin.z;
    double delta = lx * kDirection.x + ly * kDirection.y + lz * kDirection.z;
    double px = lx - delta * kDirection.x, py = ly - delta * kDirection.y,
           pz = lz - delta * kDirection.z;
    return {delta, std::sqrt(px * px + py * py + pz * pz)};
}

void expect_equiangular_well_formed(const EquiAngularSampler& sampler, float t0, float t1) {
    Rng rng(StreamKey{41, 0, 1, 0});
    for (int i = 0; i < 20000 + 3; ++i) {
        float u = i == 0 ? 0.0f : (i == 1 ? kOneMinusEpsilon : (i == 2 ? 0.5f : rng.next_1d()));
        float t = sampler.sample(u);
        ASSERT_TRUE(t >= t0 && t <= t1) << "u = " << u << ": t = " << t;
        float pdf = sampler.pdf_l(t);
        ASSERT_TRUE(std::isfinite(pdf) && pdf > 0) << "t = " << t << ": pdf = " << pdf;
    }
    EXPECT_EQ(sampler.pdf_l(std::nextafter(t0, -kInfinity)), 0.0f);
    EXPECT_EQ(sampler.pdf_l(std::nextafter(t1, kInfinity)), 0.0f);
}

// The ordinary configurations: chi-square in t and, independently of how the sampler
// parameterises the range, in the angle chart theta = atan((t - delta) / D) (computed by the
// test from the geometry), where a correct sampler is uniform and a very long range is
// resolved; the density integrates to one.
TEST(MediaEquiAngular, ChiSquare) {
    const EquiAngularCase cases[] = {
        {"light beside the ray", 2.0, 0.6, 0.0f, 5.0f},
        {"light behind the origin", -3.0, 1.0, 0.0f, 10.0f},
        {"foot beyond the range", 8.0, 0.5, 1.0f, 4.0f},
        {"very long range", 5.0, 1.0, 0.0f, 1e4f},
    };
    uint64_t seed = 600;
    for (const EquiAngularCase& k : cases) {
        SCOPED_TRACE(k.name);
        const Vec3 light = light_position(k);
        EquiAngularSampler sampler(kOrigin, kDirection, light, k.t0, k.t1);
        expect_equiangular_well_formed(sampler, k.t0, k.t1);
        auto [delta, distance] = foot_and_distance(light);
        auto pdf = [&](double t) { return double(sampler.pdf_l(float(t))); };
        EXPECT_NEAR(integrate_graded(pdf, k.t0, k.t1, delta, 0.01 * distance), 1.0, 1e-4);

        ChiSquareResult r =
            chi_square_1d([&](Rng& rng) { return double(sampler.sample(rng.next_1d())); }, pdf,
                          k.t0, k.t1, 64, ++seed, delta, 0.01 * distance);
        EXPECT_TRUE(r.passed) << "t: " << r.message;

        const double theta0 = std::atan((k.t0 - delta) / distance),
                     theta1 = std::atan((k.t1 - delta) / distance);
        ChiSquareResult ra = chi_square_1d(
            [&](Rng& rng) {
                double t = sampler.sample(rng.next_1d());
                return std::clamp(std::atan((t - delta) / distance), theta0, theta1);
            },
            [&](double theta) {
                double t = delta + distance * std::tan(theta);
                return pdf(t) * distance / (std::cos(theta) * std::cos(theta));
            },
            theta0, theta1, 64, ++seed);
        EXPECT_TRUE(ra.passed) << "angle: " << ra.message;
        EXPECT_NEAR(ra.pdf_integral, 1.0, 1e-3) << ra.message;
    }
}

// The guards: a light on the ray's line (D = 0) with the foot inside and outside the range,
// a light so far away that the angle range is tiny, and a tiny distance range. The sampler
// stays in range with a finite positive density that integrates to one and matches the
// samples.
TEST(MediaEquiAngular, Guards) {
    const EquiAngularCase cases[] = {
        {"light on the line, foot inside", 3.0, 0.0, 0.0f, 10.0f},
        {"light on the line, behind the origin", -3.0, 0.0, 0.0f, 10.0f},
        {"light on the line, beyond the range", 20.0, 0.0, 0.0f, 10.0f},
        {"light very far away beside the range", 0.5, 1e7, 0.0f, 1.0f},
        {"light far away along the line", -1000.0, 1.0, 0.0f, 1.0f},
        {"light close to the line, far behind", -10.0, 1e-4, 0.0f, 10.0f},
    };
    uint64_t seed = 700;
    for (const EquiAngularCase& k : cases) {
        SCOPED_TRACE(k.name);
        const Vec3 light = light_position(k);
        EquiAngularSampler sampler(kOrigin, kDirection, light, k.t0, k.t1);
        expect_equiangular_well_formed(sampler, k.t0, k.t1);
        auto [delta, distance] = foot_and_distance(light);
        // The spike of the on-line cases is as wide as the sampler's clamped distance
        // (1e-6 of the problem's size); grade the integration down to well below it.
        const double h = std::max(distance, 1e-9 * std::max(double(k.t1 - k.t0), std::abs(delta)));
        auto pdf = [&](double t) { return double(sampler.pdf_l(float(t))); };
        EXPECT_NEAR(integrate_graded(pdf, k.t0, k.t1, delta, h), 1.0, 1e-3);
        // Chi-square only where the density is not a sub-float spike (in the foot-inside case
        // nearly every sample is the same float).
        if (k.distance == 0 && k.delta > k.t0 && k.delta < k.t1) continue;
        ChiSquareResult r =
            chi_square_1d([&](Rng& rng) { return double(sampler.sample(rng.next_1d())); }, pdf,
                          k.t0, k.t1, 64, ++seed, delta, h);
        EXPECT_TRUE(r.passed) << r.message;
    }
}

TEST(MediaEquiAngular, TinyRange) {
    for (auto [t0, t1] : {std::pair{2.0f - 1e-6f, 2.0f}, {std::nextafter(5.0f, 0.0f), 5.0f}}) {
        SCOPED_TRACE(::testing::Message() << "[" << t0 << ", " << t1 << "]");
        for (double distance : {0.0, 1e-3, 1.0}) {
            EquiAngularCase k{"tiny", double(t0) + 0.3 * (t1 - t0), distance, t0, t1};
            EquiAngularSampler sampler(kOrigin, kDirection, light_position(k), t0, t1);
            expect_equiangular_well_formed(sampler, t0, t1);
            auto pdf = [&](double t) { return double(sampler.pdf_l(float(t))); };
            // pdf_l() sees t rounded to a float, so integrate it over each float's rounding
            // cell (the points closer to it than to its neighbours), clipped to [t0, t1].
            double integral = 0;
            for (float t = t0; t <= t1; t = std::nextafter(t, kInfinity)) {
                double lo = std::max(double(t0), 0.5 * (double(std::nextafter(t, 0.0f)) + t));
                double hi = std::min(double(t1), 0.5 * (double(std::nextafter(t, kInfinity)) + t));
                integral += pdf(t) * (hi - lo);
            }
            EXPECT_NEAR(integral, 1.0, 0.05) << distance;
        }
    }
}

}  // namespace
}  // namespace render::testing
