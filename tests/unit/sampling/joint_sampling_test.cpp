// The sampling steps of joint path sampling (docs/design/media.md, "Joint path sampling"):
// U3 (core/sampling/joint_eye_distance.h), U2 (joint_direction.h) and U1 on a half-line
// (half_line_equiangular.h; the truncated U1 that volpt uses is EquiAngularSampler, tested in
// equiangular_test). Each is chi-square tested against its density in a chart computed by the
// test from the geometry (so the test does not share the sampler's parameterisation); the
// product of the three densities is checked against G(a, b) / (pi^3 C) on random
// configurations; the hard cases check that every sample and density stays finite. Fixed seeds
// throughout.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "core/integrators/mis.h"
#include "core/math/frame.h"
#include "core/sampling/equiangular.h"
#include "core/sampling/half_line_equiangular.h"
#include "core/sampling/joint_direction.h"
#include "core/sampling/joint_eye_distance.h"
#include "tests/support/chi_square.h"

namespace render::testing {
namespace {

// The chi-square checks of this file, Sidak-corrected together (tests/support/chi_square.h).
ChiSquareFamily family;

constexpr double kPi64 = 3.14159265358979323846;

const Vec3 kOrigin(0.3f, -1.0f, 2.0f);
const Vec3 kDirection = normalize(Vec3(1.0f, 2.0f, -0.5f));
const Vec3 kPerpendicular = normalize(cross(kDirection, Vec3(0, 0, 1)));

// A point at ray distance `along` of its foot point and distance `across` from the ray's line.
Vec3 point_beside_ray(double along, double across) {
    return kOrigin + kDirection * float(along) + kPerpendicular * float(across);
}

// The test's own foot distance and line distance of `light` (double).
std::pair<double, double> foot_and_distance(const Vec3& light) {
    const double lx = double(light.x) - kOrigin.x, ly = double(light.y) - kOrigin.y,
                 lz = double(light.z) - kOrigin.z;
    const double delta = lx * kDirection.x + ly * kDirection.y + lz * kDirection.z;
    const double px = lx - delta * kDirection.x, py = ly - delta * kDirection.y,
                 pz = lz - delta * kDirection.z;
    return {delta, std::sqrt(px * px + py * py + pz * pz)};
}

bool finite_positive(double x) {
    return std::isfinite(x) && x > 0;
}

// ---- U3: distance on the eye ray ----------------------------------------------------------

// A camera ray (origin d, unit direction w) and a light point a, uniform in [-2, 2]^3 and over
// directions (by rejection from the unit ball), for the random-configuration tests below.
struct CameraRayAndLight {
    Vec3 d, a, w;
};
CameraRayAndLight random_camera_ray_and_light(Rng& rng) {
    auto uniform = [&](float lo, float hi) { return lo + (hi - lo) * rng.next_1d(); };
    const Vec3 d(uniform(-2, 2), uniform(-2, 2), uniform(-2, 2));
    const Vec3 a(uniform(-2, 2), uniform(-2, 2), uniform(-2, 2));
    Vec3 w;
    do w = Vec3(uniform(-1, 1), uniform(-1, 1), uniform(-1, 1));
    while (length_squared(w) > 1 || length_squared(w) < 1e-4f);
    return {d, a, normalize(w)};
}

struct EyeCase {
    const char* name;
    double delta, distance;
    float t0, t1;
};

void expect_eye_sampler_well_formed(const JointEyeDistanceSampler& sampler, float t0, float t1) {
    Rng rng(StreamKey{51, 0, 1, 0});
    for (int i = 0; i < 20003; ++i) {
        const float u = i == 0 ? 0.0f : (i == 1 ? kOneMinusEpsilon : rng.next_1d());
        const float t = sampler.sample(u);
        ASSERT_TRUE(t >= t0 && t <= t1) << "u = " << u << ": t = " << t;
        ASSERT_TRUE(finite_positive(sampler.pdf_l(t))) << "t = " << t;
    }
    EXPECT_EQ(sampler.pdf_l(std::nextafter(t0, -kInfinity)), 0.0f);
    EXPECT_EQ(sampler.pdf_l(std::nextafter(t1, kInfinity)), 0.0f);
}

// In t, and in the chart v = asinh((t - delta) / D) computed by the test, where a correct
// sampler is uniform. 5 configurations x 2 charts.
CHI_SQUARE_TEST(family, JointSamplingEyeDistance, ChiSquare, 10) {
    const EyeCase cases[] = {
        {"light beside the ray", 2.0, 0.6, 0.0f, 5.0f},
        {"light behind the origin", -3.0, 1.0, 0.0f, 10.0f},
        {"foot beyond the range", 8.0, 0.5, 1.0f, 4.0f},
        {"very long range", 5.0, 1.0, 0.0f, 1e4f},
        {"light close to the line", 4.0, 1e-3, 0.0f, 10.0f},
    };
    uint64_t seed = 100;
    for (const EyeCase& k : cases) {
        SCOPED_TRACE(k.name);
        const Vec3 light = point_beside_ray(k.delta, k.distance);
        const JointEyeDistanceSampler sampler(kOrigin, kDirection, light, k.t0, k.t1);
        expect_eye_sampler_well_formed(sampler, k.t0, k.t1);
        const auto [delta, distance] = foot_and_distance(light);
        // The density the specification states, written out by the test.
        const double c =
            std::asinh((k.t1 - delta) / distance) - std::asinh((k.t0 - delta) / distance);
        auto pdf = [&](double t) { return double(sampler.pdf_l(float(t))); };
        for (double t : {double(k.t0), 0.5 * (k.t0 + k.t1), double(k.t1)})
            EXPECT_NEAR(pdf(t), 1.0 / (c * std::hypot(distance, t - delta)), 1e-5 * pdf(t));
        EXPECT_NEAR(integrate_graded(pdf, k.t0, k.t1, delta, 0.01 * distance), 1.0, 1e-4);
        const ChiSquareResult r = chi_square_test_1d(
            family, [&](Rng& rng) { return double(sampler.sample(rng.next_1d())); }, pdf, k.t0,
            k.t1, {.cells = 64, .seed = ++seed, .peak = delta, .h = 0.01 * distance});
        EXPECT_TRUE(r.passed) << "t: " << r.message;

        const double v0 = std::asinh((k.t0 - delta) / distance),
                     v1 = std::asinh((k.t1 - delta) / distance);
        const ChiSquareResult rv = chi_square_test_1d(
            family,
            [&](Rng& rng) {
                const double t = sampler.sample(rng.next_1d());
                return std::clamp(std::asinh((t - delta) / distance), v0, v1);
            },
            [&](double v) {
                return pdf(delta + distance * std::sinh(v)) * distance * std::cosh(v);
            },
            v0, v1, {.cells = 64, .seed = ++seed, .peak = std::nullopt, .h = 0});
        EXPECT_TRUE(rv.passed) << "asinh chart: " << rv.message;
        EXPECT_NEAR(rv.pdf_integral, 1.0, 1e-3);
    }
}

// ---- U2: direction at the first vertex ------------------------------------------------------

// In the chart (theta, phi) about the axis c -> a, built by the test: the density there is
// p(w) sin(theta) = (pi - theta) / pi^3, smooth, so the chi-square cells integrate it exactly.
// 3 configurations.
CHI_SQUARE_TEST(family, JointSamplingDirection, ChiSquare, 3) {
    const Vec3 lights[] = {Vec3(2.0f, 0.5f, -1.0f), Vec3(0.0f, 0.0f, -1e-3f),
                           Vec3(-40.0f, 30.0f, 1.0f)};
    const Vec3 c(0.2f, -0.1f, 0.4f);
    uint64_t seed = 200;
    for (const Vec3& light : lights) {
        const JointDirectionSampler sampler(c, light);
        const Vec3 axis = normalize(light - c);
        const Frame frame = Frame::from_normal(axis);
        auto chart = [&](const Vec3& w) {
            const Vec3 l = frame.to_local(w);
            double phi = std::atan2(double(l.y), double(l.x));
            if (phi < 0) phi += 2 * kPi64;
            const double s = std::hypot(double(l.x), double(l.y));
            return Vec2(float(std::atan2(s, double(l.z))), float(phi));
        };
        // The sampler's density against the formula, at directions from the test's own frame.
        for (double theta : {1e-4, 0.3, 1.5, 3.0, kPi64 - 1e-5})
            for (double phi : {0.1, 4.0}) {
                const Vec3 w = normalize(frame.to_world(Vec3(float(std::sin(theta) * std::cos(phi)),
                                                             float(std::sin(theta) * std::sin(phi)),
                                                             float(std::cos(theta)))));
                const double expected = (kPi64 - theta) / (kPi64 * kPi64 * kPi64 * std::sin(theta));
                EXPECT_NEAR(sampler.pdf_w(w), expected, 2e-3 * expected) << theta;
            }
        const ChiSquareResult r = chi_square_test_2d(
            family,
            [&](Rng& rng) -> std::optional<Vec2> { return chart(sampler.sample(rng.next_2d())); },
            [&](Vec2 p) { return (kPi64 - p.x) / (kPi64 * kPi64 * kPi64); },
            Rect{0, kPi64, 0, 2 * kPi64}, {.resolution_x = 32, .resolution_y = 16, .seed = ++seed});
        EXPECT_TRUE(r.passed) << r.message;
        EXPECT_NEAR(r.pdf_integral, 1.0, 1e-4);
        // Samples are unit vectors whose density the sampler reports finite and positive.
        Rng rng(StreamKey{52, 0, seed, 0});
        for (int i = 0; i < 10000; ++i) {
            const Vec3 w = sampler.sample(i == 0 ? Vec2(0.0f, 0.0f) : rng.next_2d());
            ASSERT_NEAR(length_squared(w), 1.0f, 1e-5f);
            ASSERT_TRUE(finite_positive(sampler.pdf_w(w)));
        }
    }
}

// The density sample() reports with a direction (from the angle it drew) is the density pdf_w()
// evaluates for that direction, which is what the other techniques' MIS weights use for J3: they
// must agree for the weights of a path to sum to one. Also the static pdf_w(c, light, w) equals
// the sampler's. Tolerance: 1e-5 plus what a float unit direction resolves of its angle to the
// axis (components rounded to 2^-24, moving the angle by ~2^-24 and the density, which goes as
// 1 / theta near the axis, by that over theta).
TEST(JointSampling, DirectionDensityOfTheSampleIsTheDensityOfItsDirection) {
    const Vec3 lights[] = {Vec3(2.0f, 0.5f, -1.0f), Vec3(0.0f, 0.0f, -1e-3f),
                           Vec3(-40.0f, 30.0f, 1.0f), Vec3(0.2f, -0.1f, 0.4f)};
    const Vec3 c(0.2f, -0.1f, 0.4f);
    Rng rng(StreamKey{55, 0, 1, 0});
    for (const Vec3& light : lights) {
        const JointDirectionSampler sampler(c, light);
        double worst = 0;
        for (int i = 0; i < 20000; ++i) {
            const Vec2 u =
                i == 0 ? Vec2(0.0f, 0.0f) : (i == 1 ? Vec2(kOneMinusEpsilon, 0.5f) : rng.next_2d());
            float pdf = 0;
            const Vec3 w = sampler.sample(u, pdf);
            ASSERT_EQ(w, sampler.sample(u));
            ASSERT_TRUE(finite_positive(pdf)) << i;
            const float evaluated = sampler.pdf_w(w);
            ASSERT_EQ(evaluated, JointDirectionSampler::pdf_w(c, light, w));
            const double theta = kPi64 * u.x / (1.0 + std::sqrt(1.0 - double(u.x)));
            const double tolerance = 1e-5 + 4 * 0x1p-24 / std::max(theta, 1e-7);
            const double error = std::abs(double(pdf) / evaluated - 1.0);
            worst = std::max(worst, error / tolerance);
            ASSERT_LT(error, tolerance) << "u " << u.x << " " << u.y;
        }
        RecordProperty("worst_error_over_tolerance", std::to_string(worst));
    }
}

// ---- U1: distance on the half-line toward the light -------------------------------------------

// In the chart x = t / (t + t_ca) of [0, 1) (computed by the test), where the whole half-line
// is a finite range: theta from a light nearly ahead to the limit case of a light straight
// behind. 5 configurations.
CHI_SQUARE_TEST(family, JointSamplingHalfLine, ChiSquare, 5) {
    const double thetas[] = {1e-3, 0.3, 1.5, 2.8, kPi64 - 1e-7};
    const double t_ca = 1.7;
    uint64_t seed = 300;
    for (double theta : thetas) {
        SCOPED_TRACE(::testing::Message() << "theta " << theta);
        const Vec3 light = point_beside_ray(t_ca * std::cos(theta), t_ca * std::sin(theta));
        const HalfLineEquiAngularSampler sampler(kOrigin, kDirection, light);
        const auto [delta, distance] = foot_and_distance(light);
        auto pdf = [&](double t) { return double(sampler.pdf_l(float(t))); };
        if (theta < 3) {  // the formula of the specification (the limit case has its own)
            for (double t : {0.0, 0.5, 2.0, 50.0}) {
                const double expected =
                    distance /
                    ((kPi64 - theta) * (distance * distance + (t - delta) * (t - delta)));
                EXPECT_NEAR(pdf(t), expected, 1e-4 * expected + 1e-12);
            }
        }
        auto x_pdf = [&](double x) {
            const double t = t_ca * x / (1 - x);
            return pdf(t) * t_ca / ((1 - x) * (1 - x));
        };
        const double x_peak = std::max(delta, 0.0) / (std::max(delta, 0.0) + t_ca);
        const double h = std::max(0.01 * distance / t_ca, 1e-6);
        EXPECT_NEAR(integrate_graded(x_pdf, 0, 1, x_peak, h), 1.0, 1e-3);
        const ChiSquareResult r =
            chi_square_test_1d(family,
                               [&](Rng& rng) {
                                   const double t = sampler.sample(rng.next_1d());
                                   return std::clamp(t / (t + t_ca), 0.0, 1.0);
                               },
                               x_pdf, 0, 1, {.cells = 64, .seed = ++seed, .peak = x_peak, .h = h});
        EXPECT_TRUE(r.passed) << r.message;
    }
}

// ---- The product identity ---------------------------------------------------------------------

// p_U3(t_dc) p_U2(w_cb) p_U1(t_cb) = G(a, b) / (pi^3 C_T) = 1 / (pi^3 C_T |a - b|^2) for the
// vertices the three steps sample, at 10^4 random configurations (ALGORITHMS-NEXT.md 3.8 a1:
// relative error 1e-4, widened where b comes close to a by the resolution of a float unit
// direction, see below). The densities are computed in double from the float geometry.
TEST(JointSampling, ProductOfTheDensitiesIsTheGeometryTermOverTheConstant) {
    Rng rng(StreamKey{53, 0, 7, 0});
    auto uniform = [&](float lo, float hi) { return lo + (hi - lo) * rng.next_1d(); };
    int checked = 0;
    double worst = 0;
    for (int i = 0; i < 10000; ++i) {
        const auto [d, a, w] = random_camera_ray_and_light(rng);
        const float t_end = uniform(0.01f, 8.0f);
        const JointEyeDistanceSampler u3(d, w, a, 0.0f, t_end);
        const float t_dc = u3.sample(rng.next_1d());
        const Vec3 c = d + w * t_dc;
        const JointDirectionSampler u2(c, a);
        const Vec3 w_cb = u2.sample(rng.next_2d());
        const HalfLineEquiAngularSampler u1(c, w_cb, a);
        const float t_cb = u1.sample(rng.next_1d());
        // |a - b|^2 in double from the float c, w_cb and t_cb the densities saw (a float b
        // would carry its own rounding, ~1e-7 of |b|, into |a - b| when b comes close to a).
        double ab2 = 0;
        for (int k = 0; k < 3; ++k) {
            const double e = double(a[k]) - (double(c[k]) + double(w_cb[k]) * t_cb);
            ab2 += e * e;
        }
        const double product = double(u3.pdf_l(t_dc)) * u2.pdf_w(w_cb) * u1.pdf_l(t_cb);
        if (!(u3.log_range() > 0) || !(ab2 > 1e-6)) continue;  // the guards' own cases
        const double expected = 1.0 / (kPi64 * kPi64 * kPi64 * u3.log_range() * ab2);
        ASSERT_TRUE(finite_positive(product)) << i;
        // 1e-4 (the specification's bound) plus what a float unit direction w_cb can resolve:
        // its components are rounded to ~6e-8, which moves the line by ~6e-8 t_ca near a and
        // changes |a - b|^2 by that relative to |a - b| when b comes close to a.
        const double t_ca = std::sqrt(double(length_squared(a - c)));
        const double tolerance = 1e-4 + 2 * 0x1p-24 * t_ca / std::sqrt(ab2);
        const double error = std::abs(product / expected - 1.0);
        worst = std::max(worst, error / tolerance);
        EXPECT_LT(error, tolerance) << "configuration " << i << ": t_dc " << t_dc << ", t_cb "
                                    << t_cb << ", |a - b|^2 " << ab2;
        ++checked;
    }
    EXPECT_GT(checked, 9900);
    RecordProperty("worst_error_over_tolerance", std::to_string(worst));
}

// volpt's J3 (core/integrators/volumetric_path_tracer.cpp) weighs its path camera -> c -> b -> a
// with the density its sampling steps report (U3's pdf at the sampled t, U2's with the sampled
// direction, U1 truncated at the first surface: EquiAngularSampler); DL, DP and EL weigh the same
// path with J3's density evaluated from its vertices (U2 by pdf_w(c, a, w)). The four power-
// heuristic weights sum to one only if the two agree: checked at 10^4 random configurations with
// the other techniques' densities drawn over six orders of magnitude around J3's. Tolerance
// 1e-4 (the weights are floats; what the direction's rounding adds near U2's axis is bounded as
// in the test above, and configurations within 1e-2 rad of the axis are left to it).
TEST(JointSampling, WeightsOfADoubleScatteringPathSumToOne) {
    Rng rng(StreamKey{56, 0, 3, 0});
    auto uniform = [&](float lo, float hi) { return lo + (hi - lo) * rng.next_1d(); };
    int checked = 0;
    for (int i = 0; i < 10000; ++i) {
        const auto [d, a, w] = random_camera_ray_and_light(rng);
        const float t_end = uniform(0.01f, 8.0f), t_hit = uniform(0.01f, 8.0f);
        // J3's route.
        const JointEyeDistanceSampler u3(d, w, a, 0.0f, t_end);
        const float t_dc = u3.sample(rng.next_1d());
        const Vec3 c = d + w * t_dc;
        float pdf_w_cb = 0;
        const Vec2 u_direction = rng.next_2d();
        const Vec3 w_cb = JointDirectionSampler(c, a).sample(u_direction, pdf_w_cb);
        const EquiAngularSampler u1(c, w_cb, a, 0.0f, t_hit);
        const float t_cb = u1.sample(rng.next_1d());
        const double own = double(u3.pdf_l(t_dc)) * pdf_w_cb * u1.pdf_l(t_cb);
        // The other techniques' route, from the vertices.
        const double evaluated = double(JointEyeDistanceSampler(d, w, a, 0.0f, t_end).pdf_l(t_dc)) *
                                 JointDirectionSampler::pdf_w(c, a, w_cb) *
                                 EquiAngularSampler(c, w_cb, a, 0.0f, t_hit).pdf_l(t_cb);
        const double theta = kPi64 * u_direction.x / (1.0 + std::sqrt(1.0 - double(u_direction.x)));
        if (!(own > 0) || theta < 1e-2) continue;
        ASSERT_TRUE(finite_positive(evaluated)) << i;
        const double others[3] = {own * std::pow(10.0, uniform(-3, 3)),
                                  own * std::pow(10.0, uniform(-3, 3)),
                                  own * std::pow(10.0, uniform(-3, 3))};
        const double sum = double(power_heuristic4(own, others[0], others[1], others[2])) +
                           power_heuristic4(others[0], evaluated, others[1], others[2]) +
                           power_heuristic4(others[1], others[0], evaluated, others[2]) +
                           power_heuristic4(others[2], others[0], others[1], evaluated);
        EXPECT_NEAR(sum, 1.0, 1e-4) << "configuration " << i;
        ++checked;
    }
    EXPECT_GT(checked, 9500);
}

// ---- Hard cases ---------------------------------------------------------------------------------

// Every sample in range with a finite positive density, for the light on the eye ray's line
// (inside, behind, beyond the range), a vertex pair closer than 1e-6 (and coincident), and
// segments of length 1e-7 and 1e4. U3's density still integrates to one where it is not a
// sub-float spike.
TEST(JointSampling, HardCasesStayFinite) {
    struct Case {
        const char* name;
        double delta, distance;
        float t0, t1;
    };
    const Case eye_cases[] = {
        {"light on the line, inside", 3.0, 0.0, 0.0f, 10.0f},
        {"light on the line, behind", -3.0, 0.0, 0.0f, 10.0f},
        {"light on the line, beyond", 20.0, 0.0, 0.0f, 10.0f},
        {"light on the line at the origin", 0.0, 0.0, 0.0f, 10.0f},
        {"segment 1e-7", 0.5, 0.2, 1.0f, 1.0f + 1e-7f},
        {"segment 1e4", 30.0, 2.0, 0.0f, 1e4f},
        {"light 1e-7 from the line", 3.0, 1e-7, 0.0f, 10.0f},
    };
    for (const Case& k : eye_cases) {
        SCOPED_TRACE(k.name);
        const Vec3 light = point_beside_ray(k.delta, k.distance);
        const JointEyeDistanceSampler sampler(kOrigin, kDirection, light, k.t0, k.t1);
        expect_eye_sampler_well_formed(sampler, k.t0, k.t1);
        if (k.t1 - k.t0 > 1e-3f && k.distance > 0) {
            const auto [delta, distance] = foot_and_distance(light);
            auto pdf = [&](double t) { return double(sampler.pdf_l(float(t))); };
            EXPECT_NEAR(integrate_graded(pdf, k.t0, k.t1, delta, 0.01 * std::max(distance, 1e-6)),
                        1.0, 2e-3);
        }
    }
    // Vertex pairs c, a closer than 1e-6, and coincident.
    for (float gap : {1e-7f, 1e-9f, 0.0f}) {
        SCOPED_TRACE(::testing::Message() << "|a - c| = " << gap);
        const Vec3 c(0.5f, 0.25f, -0.75f);
        const Vec3 a = c + normalize(Vec3(1, 1, 1)) * gap;
        const JointDirectionSampler u2(c, a);
        Rng rng(StreamKey{54, 0, 1, 0});
        for (int i = 0; i < 2000; ++i) {
            const Vec3 w = u2.sample(rng.next_2d());
            ASSERT_TRUE(finite_positive(u2.pdf_w(w)));
            const HalfLineEquiAngularSampler u1(c, w, a);
            const float t = u1.sample(rng.next_1d());
            ASSERT_TRUE(std::isfinite(t) && t >= 0) << t;
            ASSERT_TRUE(std::isfinite(u1.pdf_l(t)) && u1.pdf_l(t) >= 0) << t;
        }
        // U3 on an eye ray that passes through both.
        const JointEyeDistanceSampler u3(c - kDirection, kDirection, a, 0.0f, 2.0f);
        expect_eye_sampler_well_formed(u3, 0.0f, 2.0f);
    }
}

}  // namespace
}  // namespace render::testing
