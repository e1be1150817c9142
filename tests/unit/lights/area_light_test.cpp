// AreaLight: illuminate / emit / radiance agree for the same point and direction, chi-square
// tests of the directions illuminate() samples against the densities radiance() claims, Monte
// Carlo irradiance against closed forms (also on the renderer's own shapes), and degenerate
// shapes.

#include "core/lights/area_light.h"

#include <gtest/gtest.h>

#include <cmath>
#include <optional>

#include "core/math/constants.h"
#include "core/shapes/sphere.h"
#include "core/shapes/triangle_mesh.h"
#include "tests/support/chi_square.h"
#include "tests/support/light_fixtures.h"

namespace render::testing {
namespace {

// The chi-square checks of this file, Sidak-corrected together (tests/support/chi_square.h).
ChiSquareFamily family;

TEST(AreaLight, IlluminateAgreesWithRadiance) {
    Parallelogram shape = ceiling();
    ASSERT_NEAR(shape.normal().z, -1.0f, 1e-6f);
    AreaLight light(&shape, Rgb(1, 2, 3));
    light.preprocess(test_scene_sphere());
    Rng rng(StreamKey{11, 0, 1, 0});
    int successes = 0;
    for (int i = 0; i < 2000; ++i) {
        Vec3 ref(rng.next_1d() * 6 - 3, rng.next_1d() * 6 - 3, rng.next_1d() * 1.5f - 0.5f);
        LightIlluminateSample s;
        if (!light.illuminate(ref, rng.next_2d(), s)) {
            EXPECT_GE(ref.z, 1.0f) << "only points above the light's plane see its back";
            continue;
        }
        ++successes;
        Vec3 hit = ref + s.wi * s.distance;
        EXPECT_NEAR(hit.z, 1.0f, 1e-5f);
        EXPECT_NEAR(s.cos_at_light, dot(shape.normal(), -s.wi), 1e-6f);
        LightRadiance r = light.radiance(hit, shape.normal(), s.wi);
        EXPECT_EQ(r.radiance, s.radiance);
        // pdf_direct_a converted to solid angle at the receiver.
        expect_close(r.pdf_direct_a * s.distance * s.distance / s.cos_at_light, s.pdf_direct_w,
                     1e-4f);
        expect_close(r.pdf_emission_w, s.pdf_emission_w, 1e-5f);
        expect_close(s.pdf_emission_w, s.cos_at_light * kInvPi / 2.0f, 1e-5f);
    }
    EXPECT_GT(successes, 1000);
    // Seen from behind: nothing.
    LightIlluminateSample s;
    EXPECT_FALSE(light.illuminate(Vec3(0, 0, 2), Vec2(0.5f, 0.5f), s));
    LightRadiance back = light.radiance(Vec3(0, 0, 1), shape.normal(), Vec3(0, 0, -1));
    EXPECT_TRUE(back.radiance.is_black());
    EXPECT_EQ(back.pdf_direct_a, 0.0f);
    expect_close(light.power(), Rgb(1, 2, 3) * (2.0f * kPi));
    EXPECT_FALSE(light.is_delta());
    EXPECT_TRUE(light.is_finite());
}

TEST(AreaLight, EmitAgreesWithIlluminateAndRadiance) {
    Parallelogram shape = ceiling();
    AreaLight light(&shape, Rgb(1, 2, 3));
    Rng rng(StreamKey{12, 0, 1, 0});
    double mean_cos = 0;
    const int n = 20000;
    for (int i = 0; i < n; ++i) {
        Vec2 u_pos = rng.next_2d();
        LightEmitSample e;
        ASSERT_TRUE(light.emit(u_pos, rng.next_2d(), e));
        EXPECT_NEAR(length(e.direction), 1.0f, 1e-5f);
        EXPECT_NEAR(e.cos_at_light, dot(e.direction, shape.normal()), 1e-5f);
        EXPECT_GT(e.cos_at_light, 0.0f);
        mean_cos += e.cos_at_light / n;
        expect_close(e.energy, Rgb(1, 2, 3) * e.cos_at_light);
        expect_close(e.pdf_direct_a, 0.5f);

        // The camera-side view of the same (point, direction) pair.
        LightRadiance r = light.radiance(e.origin, shape.normal(), -e.direction);
        expect_close(r.pdf_emission_w, e.pdf_emission_w);
        expect_close(r.pdf_direct_a, e.pdf_direct_a);
        expect_close(r.radiance * e.cos_at_light, e.energy);

        // illuminate() from a point on the emitted ray, with the u that picks this origin.
        Vec3 ref = e.origin + e.direction * 1.7f;
        LightIlluminateSample s;
        ASSERT_TRUE(light.illuminate(ref, u_pos, s));
        EXPECT_NEAR(s.distance, 1.7f, 1e-4f);
        expect_close(s.pdf_emission_w, e.pdf_emission_w, 1e-3f);
        EXPECT_NEAR(s.cos_at_light, e.cos_at_light, 1e-4f);
    }
    // Cosine-weighted directions: E[cos] = 2/3 (standard deviation of cos is 0.236).
    EXPECT_NEAR(mean_cos, 2.0 / 3.0, 5 * 0.236 / std::sqrt(double(n)));
}

CHI_SQUARE_TEST(family, AreaLight, IlluminateDirectionsChiSquareSphere, 1) {
    // An inward-facing sphere light around an off-centre receiver: illuminate() covers every
    // direction with a smooth density, which chi_square_test_sphere can resolve. The pdf is
    // what radiance() reports for a ray along w, converted to solid angle.
    TestSphere shape(Vec3(0.0f), 2.0f, /*inward=*/true);
    AreaLight light(&shape, Rgb(1));
    Vec3 ref(0.9f, -0.6f, 0.8f);
    auto sample = [&](Rng& rng) -> std::optional<Vec3> {
        LightIlluminateSample s;
        if (!light.illuminate(ref, rng.next_2d(), s)) return std::nullopt;
        return s.wi;
    };
    auto pdf = [&](const Vec3& w) {
        auto [p, n] = shape.hit_from_inside(ref, w);
        LightRadiance r = light.radiance(p, n, w);
        double d2 = length_squared(p - ref), cos = dot(n, -w);
        return double(r.pdf_direct_a) * d2 / cos;
    };
    ChiSquareResult r = chi_square_test_sphere(family, sample, pdf, ChiSquareOptions());
    EXPECT_TRUE(r.passed) << r.message;
    EXPECT_NEAR(r.pdf_integral, 1.0, 1e-3);
}

CHI_SQUARE_TEST(family, AreaLight, IlluminateDirectionsChiSquareRectangle, 1) {
    // A rectangle seen from a point: the solid-angle density checked in the rectangle's own
    // chart (s, t), where it becomes pdf_w(w(s, t)) * |d omega / d(s, t)| =
    // pdf_w * area * cos / d^2, with the Jacobian computed here from the geometry.
    Parallelogram shape(Vec3(-1, -1, 1), Vec3(0, 2, 0), Vec3(3, 0, 0));
    AreaLight light(&shape, Rgb(1));
    Vec3 ref(1.5f, 0.3f, 0.2f);
    auto sample = [&](Rng& rng) -> std::optional<Vec2> {
        LightIlluminateSample s;
        if (!light.illuminate(ref, rng.next_2d(), s)) return std::nullopt;
        auto hit = shape.intersect(ref, s.wi);
        if (!hit) return Vec2(-1, -1);  // a direction that misses the light: fails the test
        return hit->first;
    };
    auto pdf = [&](Vec2 st) {
        Vec3 p = Vec3(-1, -1, 1) + Vec3(0, 2, 0) * st.x + Vec3(3, 0, 0) * st.y;
        Vec3 w = normalize(p - ref);
        double d2 = length_squared(p - ref), cos = dot(shape.normal(), -w);
        LightRadiance r = light.radiance(p, shape.normal(), w);
        double pdf_w = double(r.pdf_direct_a) * d2 / cos;
        return pdf_w * shape.surface_area() * cos / d2;
    };
    ChiSquareResult r =
        chi_square_test_2d(family, sample, pdf, Rect{0, 1, 0, 1}, ChiSquareOptions());
    EXPECT_TRUE(r.passed) << r.message;
    EXPECT_NEAR(r.pdf_integral, 1.0, 1e-3);
}

// Form factor from a differential area to a parallel a x b rectangle with one corner above
// it, at height c (Howell's catalogue, B-3).
double corner_form_factor(double a, double b, double c) {
    double x = a / c, y = b / c, sx = std::sqrt(1 + x * x), sy = std::sqrt(1 + y * y);
    return (x / sx * std::atan(y / sx) + y / sy * std::atan(x / sy)) / (2 * M_PI);
}

TEST(AreaLight, MonteCarloIrradianceOfALargeRectangle) {
    // A 8 x 8 square at height 1 above the receiver, facing it: E = pi L F, with F the sum of
    // four corner form factors.
    Parallelogram shape(Vec3(-4, -4, 1), Vec3(0, 8, 0), Vec3(8, 0, 0));
    AreaLight light(&shape, Rgb(2));
    double reference = 2.0 * M_PI * 4 * corner_form_factor(4, 4, 1);
    expect_estimate(irradiance(light, Vec3(0.0f), Vec3(0, 0, 1), 200000, 21), reference);
    // Off-centre receiver: four rectangles of different sizes around the foot point.
    Vec3 p(1.0f, -2.5f, 0.0f);
    double f = corner_form_factor(5, 1.5, 1) + corner_form_factor(3, 1.5, 1) +
               corner_form_factor(5, 6.5, 1) + corner_form_factor(3, 6.5, 1);
    expect_estimate(irradiance(light, p, Vec3(0, 0, 1), 200000, 22), 2.0 * M_PI * f);
}

TEST(AreaLight, MonteCarloIrradianceOfASphere) {
    // A sphere of radius r at distance D, entirely above the horizon: E = pi L (r / D)^2.
    TestSphere shape(Vec3(0, 0, 3), 1.0f, /*inward=*/false);
    AreaLight light(&shape, Rgb(5));
    expect_estimate(irradiance(light, Vec3(0.0f), Vec3(0, 0, 1), 200000, 23), 5.0 * M_PI / 9.0);
}

TEST(AreaLight, OnTheSceneShapes) {
    // The same closed forms with the renderer's own shapes: an 8 x 8 rectangle mesh at height
    // 1 facing down (Mitsuba's rectangle, scaled, flipped and lifted) and an analytic sphere.
    Transform to_world = Transform::translate(Vec3(0, 0, 1)) *
                         Transform::rotate(Vec3(1, 0, 0), 180) * Transform::scale(Vec3(4, 4, 1));
    TriangleMesh rectangle(make_rectangle_mesh(), to_world, false, false, "rectangle");
    AreaLight quad_light(&rectangle, Rgb(2));
    expect_estimate(irradiance(quad_light, Vec3(0.0f), Vec3(0, 0, 1), 200000, 24),
                    2.0 * M_PI * 4 * corner_form_factor(4, 4, 1));
    Sphere sphere(Vec3(0, 0, 3), 1.0f, false, "sphere");
    AreaLight sphere_light(&sphere, Rgb(5));
    expect_estimate(irradiance(sphere_light, Vec3(0.0f), Vec3(0, 0, 1), 200000, 25),
                    5.0 * M_PI / 9.0);
    // illuminate() and radiance() agree on the mesh.
    Rng rng(StreamKey{26, 0, 1, 0});
    for (int i = 0; i < 1000; ++i) {
        LightIlluminateSample s;
        ASSERT_TRUE(quad_light.illuminate(Vec3(0.5f, -0.3f, 0), rng.next_2d(), s));
        LightRadiance r =
            quad_light.radiance(Vec3(0.5f, -0.3f, 0) + s.wi * s.distance, Vec3(0, 0, -1), s.wi);
        EXPECT_EQ(r.radiance, s.radiance);
        expect_close(r.pdf_direct_a * s.distance * s.distance / s.cos_at_light, s.pdf_direct_w,
                     1e-4f);
        expect_close(r.pdf_emission_w, s.pdf_emission_w, 1e-4f);
    }
}

TEST(AreaLight, ZeroAreaShapeEmitsNothing) {
    Parallelogram shape(Vec3(0, 0, 1), Vec3(1, 0, 0), Vec3(0, 0, 0));
    AreaLight light(&shape, Rgb(1));
    LightIlluminateSample s;
    LightEmitSample e;
    EXPECT_FALSE(light.illuminate(Vec3(0.0f), Vec2(0.5f, 0.5f), s));
    EXPECT_FALSE(light.emit(Vec2(0.5f, 0.5f), Vec2(0.5f, 0.5f), e));
    LightRadiance r = light.radiance(Vec3(0, 0, 1), Vec3(0, 0, -1), Vec3(0, 0, 1));
    EXPECT_TRUE(r.radiance.is_black());
    EXPECT_EQ(r.pdf_direct_a, 0.0f);
    EXPECT_EQ(light.power(), Rgb(0.0f));
}

TEST(AreaLight, GrazingAndCornerSamplesStayFinite) {
    Parallelogram shape = ceiling();
    AreaLight light(&shape, Rgb(1));
    // A receiver in the light's plane sees it edge-on (cos = 0): no sample.
    LightIlluminateSample s;
    EXPECT_FALSE(light.illuminate(Vec3(5, 0, 1), Vec2(0.5f, 0.5f), s));
    for (Vec2 u : {Vec2(0, 0), Vec2(kOneMinusEpsilon, kOneMinusEpsilon), Vec2(0, 0.5f)}) {
        LightEmitSample e;
        if (light.emit(u, u, e)) {
            EXPECT_TRUE(is_finite(e.direction) && e.energy.is_finite());
            EXPECT_TRUE(std::isfinite(e.pdf_emission_w));
        }
        if (light.illuminate(Vec3(0.1f, 0.2f, 0.0f), u, s)) {
            EXPECT_TRUE(std::isfinite(s.pdf_direct_w) && is_finite(s.wi));
        }
    }
}

}  // namespace
}  // namespace render::testing
