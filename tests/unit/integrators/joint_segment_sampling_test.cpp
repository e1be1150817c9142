// The sampling steps of J2, the segment-segment joint connection of bpt (docs/design/media.md, "J2:
// segment-segment connections"): B2, the distance of the light-side vertex b on the light ray
// (core/sampling/joint_light_distance.h), then B1, the distance of the eye-side vertex c on the
// eye half-line by equi-angular sampling toward b (half_line_equiangular.h). B2 is chi-square
// tested against a density the test writes from the geometry alone (1 / the distance of b(t)
// from the eye line, normalised by quadrature), B1 against its formula at vertices b drawn by
// B2; the product identity p_B2 p_B1 = G(b, c) sin(alpha) / (C (pi - theta_b)) is checked at
// 10^4 random configurations; the hard cases check that samples and densities stay finite.
// Fixed seeds throughout.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "core/integrators/joint_segment.h"
#include "core/sampling/half_line_equiangular.h"
#include "core/sampling/joint_light_distance.h"
#include "tests/support/chi_square.h"

namespace render::testing {
namespace {

// The chi-square checks of this file, Sidak-corrected together (tests/support/chi_square.h).
ChiSquareFamily family;

constexpr double kPi64 = 3.14159265358979323846;

bool finite_positive(double x) {
    return std::isfinite(x) && x > 0;
}

// The test's own distance of point p from the line (e, u), in double.
double distance_to_line(const double* p, const Vec3& e, const Vec3& u) {
    const double w[3] = {p[0] - e.x, p[1] - e.y, p[2] - e.z};
    const double c[3] = {w[1] * u.z - w[2] * u.y, w[2] * u.x - w[0] * u.z, w[0] * u.y - w[1] * u.x};
    return std::sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]);
}

struct SegmentCase {
    const char* name;
    Vec3 light_origin, light_direction, eye_origin, eye_direction;
    float range;
};

Vec3 unit(float x, float y, float z) {
    return normalize(Vec3(x, y, z));
}

const SegmentCase kCases[] = {
    {"skew lines", Vec3(0, 0, 0), unit(1, 0.2f, 0), Vec3(2, -1, 0.5f), unit(0, 1, 0.1f), 6.0f},
    {"closest approach behind the light origin", Vec3(0, 0, 0), unit(1, 0, 0), Vec3(-3, -1, 0.3f),
     unit(0.2f, 1, 0), 5.0f},
    {"lines that nearly meet", Vec3(0, 0, 0), unit(1, 0, 0), Vec3(2, -1, 1e-3f), unit(0, 1, 0),
     5.0f},
    {"nearly parallel lines", Vec3(0, 0, 0), unit(1, 0, 0), Vec3(0, 0.5f, 0), unit(1, 0.01f, 0),
     8.0f},
    {"long range", Vec3(0, 0, 0), unit(0, 0, 1), Vec3(1, 0, 5), unit(0, 1, 0), 1e4f},
};

// B2 in t: against p(t) = (1 / h(t)) / integral of 1 / h, h(t) the distance of b(t) from the eye
// line computed by the test; and its integral. 5 configurations.
CHI_SQUARE_TEST(family, JointSegmentLightDistance, ChiSquare, 5) {
    uint64_t seed = 400;
    for (const SegmentCase& k : kCases) {
        SCOPED_TRACE(k.name);
        const JointLightDistanceSampler sampler(k.light_origin, k.light_direction, k.eye_origin,
                                                k.eye_direction, k.range);
        auto inverse_h = [&](double t) {
            const double b[3] = {k.light_origin.x + k.light_direction.x * t,
                                 k.light_origin.y + k.light_direction.y * t,
                                 k.light_origin.z + k.light_direction.z * t};
            return 1.0 / distance_to_line(b, k.eye_origin, k.eye_direction);
        };
        const double peak = std::clamp(sampler.geometry().foot.delta, 0.0, double(k.range));
        const double h = 1e-3;
        const double norm = integrate_graded(inverse_h, 0, k.range, peak, h);
        auto expected = [&](double t) { return inverse_h(t) / norm; };
        auto pdf = [&](double t) { return double(sampler.pdf_l(float(t))); };
        for (double t : {0.0, 0.3 * k.range, double(k.range)})
            EXPECT_NEAR(pdf(t), expected(t), 2e-4 * expected(t)) << t;
        EXPECT_NEAR(integrate_graded(pdf, 0, k.range, peak, h), 1.0, 1e-4);
        EXPECT_EQ(sampler.pdf_l(std::nextafter(k.range, kInfinity)), 0.0f);
        EXPECT_EQ(sampler.pdf_l(-1e-6f), 0.0f);
        const ChiSquareResult r = chi_square_test_1d(
            family, [&](Rng& rng) { return double(sampler.sample(rng.next_1d())); }, pdf, 0,
            k.range, {.cells = 64, .seed = ++seed, .peak = peak, .h = h});
        EXPECT_TRUE(r.passed) << r.message;
    }
}

// B1 given a vertex b drawn by B2: half-line equi-angular on the eye ray toward b, in the chart
// x = s / (s + |b - e|) of [0, 1) (computed by the test), against the formula
// p(s) = h / ((pi - theta_b) (h^2 + (s - delta)^2)) written out by the test. 2 configurations x
// 2 vertices.
CHI_SQUARE_TEST(family, JointSegmentEyeDistance, ChiSquare, 4) {
    uint64_t seed = 500;
    for (int c = 0; c < 2; ++c) {
        const SegmentCase& k = kCases[c];
        const JointLightDistanceSampler b2(k.light_origin, k.light_direction, k.eye_origin,
                                           k.eye_direction, k.range);
        for (float u : {0.3f, 0.8f}) {
            const float t = b2.sample(u);
            const Vec3 b = k.light_origin + k.light_direction * t;
            SCOPED_TRACE(::testing::Message() << k.name << ", t " << t);
            const HalfLineEquiAngularSampler b1(k.eye_origin, k.eye_direction, b);
            const Vec3 eb = b - k.eye_origin;
            const double t_eb = length(eb);
            const double delta = dot(eb, k.eye_direction);
            const double h = std::sqrt(std::max(t_eb * t_eb - delta * delta, 0.0));
            const double theta = std::atan2(h, delta);
            auto formula = [&](double s) {
                return h / ((kPi64 - theta) * (h * h + (s - delta) * (s - delta)));
            };
            auto pdf = [&](double s) { return double(b1.pdf_l(float(s))); };
            for (double s : {0.0, 0.5, 3.0, 40.0})
                EXPECT_NEAR(pdf(s), formula(s), 1e-4 * formula(s)) << s;
            auto x_pdf = [&](double x) {
                const double s = t_eb * x / (1 - x);
                return pdf(s) * t_eb / ((1 - x) * (1 - x));
            };
            const double x_peak = std::max(delta, 0.0) / (std::max(delta, 0.0) + t_eb);
            const double hx = std::max(0.01 * h / t_eb, 1e-6);
            EXPECT_NEAR(integrate_graded(x_pdf, 0, 1, x_peak, hx), 1.0, 1e-3);
            const ChiSquareResult r = chi_square_test_1d(
                family,
                [&](Rng& rng) {
                    const double s = b1.sample(rng.next_1d());
                    return std::clamp(s / (s + t_eb), 0.0, 1.0);
                },
                x_pdf, 0, 1, {.cells = 64, .seed = ++seed, .peak = x_peak, .h = hx});
            EXPECT_TRUE(r.passed) << r.message;
        }
    }
}

// p_B2(t) p_B1(s | b) = G(b, c) sin(alpha) / (C (pi - theta_b)) at 10^4 random configurations,
// with sin(alpha), theta_b and |b - c| computed by the test in double from the float geometry
// the densities saw. Relative error 1e-4, plus what a float b resolves of its distance h from
// the eye line (b's components are rounded to ~6e-8 |b|).
TEST(JointSegmentSampling, ProductOfTheDensitiesIsTheGeometryTermOverTheConstant) {
    Rng rng(StreamKey{57, 0, 7, 0});
    auto uniform = [&](float lo, float hi) { return lo + (hi - lo) * rng.next_1d(); };
    auto direction = [&] {
        Vec3 w;
        do w = Vec3(uniform(-1, 1), uniform(-1, 1), uniform(-1, 1));
        while (length_squared(w) > 1 || length_squared(w) < 1e-4f);
        return normalize(w);
    };
    int checked = 0;
    for (int i = 0; i < 10000; ++i) {
        const Vec3 o(uniform(-2, 2), uniform(-2, 2), uniform(-2, 2));
        const Vec3 e(uniform(-2, 2), uniform(-2, 2), uniform(-2, 2));
        const Vec3 w = direction(), u = direction();
        const float range = uniform(0.01f, 8.0f);
        const JointLightDistanceSampler b2(o, w, e, u, range);
        const float t = b2.sample(rng.next_1d());
        const Vec3 b = o + w * t;
        const HalfLineEquiAngularSampler b1(e, u, b);
        const float s = b1.sample(rng.next_1d());
        const double bd[3] = {b.x, b.y, b.z};
        const double h = distance_to_line(bd, e, u);
        double along = 0, bc2 = 0;
        for (int k = 0; k < 3; ++k) along += (bd[k] - e[k]) * u[k];
        for (int k = 0; k < 3; ++k) {
            const double d = bd[k] - (double(e[k]) + double(u[k]) * s);
            bc2 += d * d;
        }
        const double theta = std::atan2(h, along);
        const Vec3 wu = cross(w, u);
        const double sin_alpha = std::sqrt(double(length_squared(wu)));
        // The guards' own cases: uniform B2, the limit forms of B1, b on the eye line.
        if (!(b2.log_range() > 0) || theta < 1e-4 || kPi64 - theta < 1e-4 || h < 1e-3 ||
            !(bc2 > 1e-8) || !std::isfinite(s))
            continue;
        const double product = double(b2.pdf_l(t)) * double(b1.pdf_l(s));
        const double expected = sin_alpha / (bc2 * b2.log_range() * (kPi64 - theta));
        ASSERT_TRUE(finite_positive(product)) << i;
        const double scale =
            std::max({std::abs(double(b.x)), std::abs(double(b.y)), std::abs(double(b.z)), 1.0});
        const double tolerance = 1e-4 + 4 * 0x1p-24 * scale / h;
        EXPECT_NEAR(product / expected, 1.0, tolerance)
            << "configuration " << i << ": t " << t << ", s " << s << ", h " << h;
        ++checked;
    }
    EXPECT_GT(checked, 9000);
}

// Parallel lines (exactly and 1e-7 off), lines that meet, the eye origin on the light ray,
// ranges of 1e-7 and 1e4, b closer than 1e-6 to the eye line: every B2 sample in range with a
// finite positive density, and B1 toward it finite.
TEST(JointSegmentSampling, HardCasesStayFinite) {
    const SegmentCase cases[] = {
        {"parallel", Vec3(0, 0, 0), unit(1, 0, 0), Vec3(0, 1, 0), unit(1, 0, 0), 5.0f},
        {"antiparallel", Vec3(0, 0, 0), unit(1, 0, 0), Vec3(3, 1e-3f, 0), unit(-1, 0, 0), 5.0f},
        {"1e-7 rad off parallel", Vec3(0, 0, 0), unit(1, 0, 0), Vec3(0, 1, 0), unit(1, 1e-7f, 0),
         5.0f},
        {"same line", Vec3(0, 0, 0), unit(1, 0, 0), Vec3(2, 0, 0), unit(1, 0, 0), 5.0f},
        {"lines meet", Vec3(0, 0, 0), unit(1, 0, 0), Vec3(2, -1, 0), unit(0, 1, 0), 5.0f},
        {"eye origin on the light ray", Vec3(0, 0, 0), unit(1, 0, 0), Vec3(1, 0, 0), unit(0, 0, 1),
         5.0f},
        {"range 1e-7", Vec3(0, 0, 0), unit(1, 0, 0), Vec3(2, -1, 0.5f), unit(0, 1, 0), 1e-7f},
        {"range 1e4", Vec3(0, 0, 0), unit(1, 0, 0), Vec3(2, -1, 0.5f), unit(0, 1, 0), 1e4f},
        {"b within 1e-7 of the eye line", Vec3(0, 0, 0), unit(1, 0, 0), Vec3(2, -1, 1e-7f),
         unit(0, 1, 0), 5.0f},
    };
    for (const SegmentCase& k : cases) {
        SCOPED_TRACE(k.name);
        const JointLightDistanceSampler b2(k.light_origin, k.light_direction, k.eye_origin,
                                           k.eye_direction, k.range);
        Rng rng(StreamKey{58, 0, 1, 0});
        for (int i = 0; i < 5000; ++i) {
            const float u = i == 0 ? 0.0f : (i == 1 ? kOneMinusEpsilon : rng.next_1d());
            const float t = b2.sample(u);
            ASSERT_TRUE(t >= 0 && t <= k.range) << "u " << u << ": t " << t;
            ASSERT_TRUE(finite_positive(b2.pdf_l(t))) << "t " << t;
            const HalfLineEquiAngularSampler b1(k.eye_origin, k.eye_direction,
                                                k.light_origin + k.light_direction * t);
            const float s = b1.sample(rng.next_1d());
            ASSERT_TRUE(s >= 0 && !std::isnan(s)) << s;
            ASSERT_TRUE(std::isfinite(b1.pdf_l(s)) && b1.pdf_l(s) >= 0) << s;
        }
    }
    // The range helper: inside the sphere a positive exit, outside and missing 0.
    const SceneSphere sphere{Vec3(0, 0, 0), 2.0f};
    EXPECT_NEAR(light_ray_range(sphere, Vec3(0, 0, 0), unit(1, 0, 0)), 2.0f, 1e-6f);
    EXPECT_NEAR(light_ray_range(sphere, Vec3(-3, 0, 0), unit(1, 0, 0)), 5.0f, 1e-5f);
    EXPECT_EQ(light_ray_range(sphere, Vec3(-3, 5, 0), unit(1, 0, 0)), 0.0f);
    EXPECT_EQ(light_ray_range(sphere, Vec3(3, 0, 0), unit(1, 0, 0)), 0.0f);
}

}  // namespace
}  // namespace render::testing
