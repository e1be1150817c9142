// Phase functions (core/media/isotropic_phase.h, henyey_greenstein.h) against their densities:
// chi-square tests of the sampled directions (tests/support/chi_square.h), numerical
// normalisation, an independent closed form, reciprocity and the mean cosine, stated in
// standard errors. Fixed seeds throughout.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <optional>
#include <utility>

#include "core/math/constants.h"
#include "core/media/henyey_greenstein.h"
#include "core/media/isotropic_phase.h"
#include "tests/support/chi_square.h"
#include "tests/support/statistics.h"

namespace render::testing {
namespace {

// The chi-square checks of this file, Sidak-corrected together (tests/support/chi_square.h).
ChiSquareFamily family;

// Deviations of a sample mean from its expectation, in standard errors.
constexpr double kStandardErrors = 5.0;

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
        family, [&](Rng& rng) -> std::optional<Vec3> { return phase.sample(wo, rng.next_2d()).wi; },
        [&](const Vec3& wi) { return double(phase.p(wo, wi)); }, ChiSquareOptions{.seed = seed});
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
    return chi_square_test_2d(family, sample, pdf, Rect{0.0, 2.0 * M_PI, z_min, 1.0},
                              ChiSquareOptions{.seed = seed});
}

CHI_SQUARE_TEST(family, MediaPhase, Isotropic, 1) {
    IsotropicPhase phase;
    expect_well_formed(phase, kWoTilted);
    expect_passes(phase_chi_square_sphere(phase, kWoTilted, 101));
    EXPECT_NEAR(integrate_phase(phase, kWoTilted), 1.0, 1e-4);
    EXPECT_NEAR(phase.p(kWoTilted, kWoLow), 1.0 / (4.0 * M_PI), 1e-7);
}

// 6 values of g x 3 directions wo.
CHI_SQUARE_TEST(family, MediaPhase, HenyeyGreensteinChiSquareWholeSphere, 18) {
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

// 2 (g, cap) pairs x 2 directions wo.
CHI_SQUARE_TEST(family, MediaPhase, HenyeyGreensteinChiSquareLobe, 4) {
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
            MeanAccumulator cosine;
            for (int i = 0; i < n; ++i) cosine.add(dot(-wo, phase.sample(wo, rng.next_2d()).wi));
            EXPECT_NEAR(cosine.mean(), g, kStandardErrors * cosine.standard_error())
                << "standard error " << cosine.standard_error();
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

}  // namespace
}  // namespace render::testing
