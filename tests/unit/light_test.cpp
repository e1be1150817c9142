// Lights: every sampling routine against the others (illuminate / emit / radiance report the
// same radiance and densities for the same point and direction), chi-square tests of the
// direction samplers against the densities that radiance() claims, Monte Carlo irradiance
// against closed forms, degenerate inputs, and the factory's error messages.

#include <OpenImageIO/imageio.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "core/lights/area_light.h"
#include "core/lights/constant_light.h"
#include "core/lights/directional_light.h"
#include "core/lights/envmap_light.h"
#include "core/lights/light_factory.h"
#include "core/lights/point_light.h"
#include "core/math/constants.h"
#include "core/sampling/warp.h"
#include "core/shapes/sphere.h"
#include "core/shapes/triangle_mesh.h"
#include "tests/support/chi_square.h"

namespace render::testing {
namespace {

constexpr int kChiSquareTests = 4;  // in this file, for the Sidak correction

ChiSquareOptions chi_options() {
    ChiSquareOptions o;
    o.test_count = kChiSquareTests;
    return o;
}

// Relative comparison for densities and radiance values.
void expect_close(float a, float b, float rel = 1e-4f) {
    EXPECT_NEAR(a, b, rel * std::max(std::abs(a), std::abs(b))) << a << " vs " << b;
}
void expect_close(const Rgb& a, const Rgb& b, float rel = 1e-5f) {
    for (int c = 0; c < 3; ++c) expect_close(a[c], b[c], rel);
}

// ---------------------------------------------------------------------------------------
// Test-only shapes (analytic, so that the tests know the exact geometry).

// p0 + s e1 + t e2 for (s, t) in [0, 1]^2, normal along cross(e1, e2).
class Parallelogram final : public Shape {
  public:
    Parallelogram(const Vec3& p0, const Vec3& e1, const Vec3& e2) : p0_(p0), e1_(e1), e2_(e2) {
        Vec3 c = cross(e1, e2);
        area_ = length(c);
        n_ = area_ > 0 ? c / area_ : Vec3(0, 0, 1);
    }
    unsigned attach(RTCDevice, RTCScene) const override { return 0; }
    void fill_interaction(const Ray&, float, unsigned, float, float,
                          SurfaceInteraction&) const override {}
    Aabb bounds() const override {
        Aabb b;
        for (Vec3 p : {p0_, p0_ + e1_, p0_ + e2_, p0_ + e1_ + e2_}) b.expand(p);
        return b;
    }
    float surface_area() const override { return area_; }
    ShapeSample sample_area(Vec2 u) const override {
        return {p0_ + e1_ * u.x + e2_ * u.y, n_, area_ > 0 ? 1.0f / area_ : 0.0f};
    }
    std::string to_string() const override { return "Parallelogram"; }

    const Vec3& normal() const { return n_; }
    // (s, t) of a point on the plane (e1, e2 orthogonal in these tests).
    Vec2 coordinates(const Vec3& p) const {
        Vec3 d = p - p0_;
        return {dot(d, e1_) / length_squared(e1_), dot(d, e2_) / length_squared(e2_)};
    }
    // Ray hit: (s, t) and distance, or nothing.
    std::optional<std::pair<Vec2, float>> intersect(const Vec3& o, const Vec3& w) const {
        float denom = dot(w, n_);
        if (denom == 0) return std::nullopt;
        float t = dot(p0_ - o, n_) / denom;
        if (!(t > 0)) return std::nullopt;
        Vec2 st = coordinates(o + w * t);
        if (st.x < 0 || st.x > 1 || st.y < 0 || st.y > 1) return std::nullopt;
        return std::pair{st, t};
    }

  private:
    Vec3 p0_, e1_, e2_, n_;
    float area_;
};

// A sphere whose normals point outward or (`inward`) toward its centre.
class TestSphere final : public Shape {
  public:
    TestSphere(const Vec3& c, float r, bool inward) : c_(c), r_(r), inward_(inward) {}
    unsigned attach(RTCDevice, RTCScene) const override { return 0; }
    void fill_interaction(const Ray&, float, unsigned, float, float,
                          SurfaceInteraction&) const override {}
    Aabb bounds() const override {
        Aabb b;
        b.expand(c_ - Vec3(r_));
        b.expand(c_ + Vec3(r_));
        return b;
    }
    float surface_area() const override { return 4.0f * kPi * r_ * r_; }
    ShapeSample sample_area(Vec2 u) const override {
        Vec3 d = warp::square_to_uniform_sphere(u);
        return {c_ + d * r_, inward_ ? -d : d, 1.0f / surface_area()};
    }
    std::string to_string() const override { return "TestSphere"; }
    // Far hit from a point inside the sphere: point and normal.
    std::pair<Vec3, Vec3> hit_from_inside(const Vec3& o, const Vec3& w) const {
        Vec3 oc = o - c_;
        float b = dot(oc, w), cc = length_squared(oc) - r_ * r_;
        float t = -b + std::sqrt(b * b - cc);
        Vec3 p = o + w * t;
        Vec3 n = normalize(p - c_);
        return {p, inward_ ? -n : n};
    }

  private:
    Vec3 c_;
    float r_;
    bool inward_;
};

SceneSphere test_scene_sphere() {
    return SceneSphere{Vec3(0.5f, -1.0f, 2.0f), 3.0f};
}

// Mean and standard error of a Monte Carlo estimator of irradiance at `p` with normal `n`
// from illuminate() (contribution = radiance * cos / pdf_direct_w, zero when it fails).
struct Estimate {
    double mean, standard_error;
};
Estimate irradiance(const Light& light, const Vec3& p, const Vec3& n, int samples, uint64_t seed) {
    Rng rng(StreamKey{seed, 0, 1, 0});
    double sum = 0, sum2 = 0;
    for (int i = 0; i < samples; ++i) {
        LightIlluminateSample s;
        double f = 0;
        if (light.illuminate(p, rng.next_2d(), s))
            f = double(s.radiance.r) * std::max(0.0f, dot(s.wi, n)) / double(s.pdf_direct_w);
        sum += f;
        sum2 += f * f;
    }
    double mean = sum / samples, var = std::max(0.0, sum2 / samples - mean * mean);
    return {mean, std::sqrt(var / samples)};
}

// The estimate lies within k standard errors of the reference (plus float round-off).
constexpr double kStandardErrors = 5.0;
void expect_estimate(const Estimate& e, double reference) {
    EXPECT_NEAR(e.mean, reference, kStandardErrors * e.standard_error + 1e-5 * reference)
        << "standard error " << e.standard_error;
}

// ---------------------------------------------------------------------------------------
// Point light

TEST(PointLight, IlluminateFollowsSmallVcmConvention) {
    PointLight light(Vec3(1, 2, 3), Rgb(4, 5, 6));
    light.preprocess(test_scene_sphere());
    Vec3 ref(1, 2, 0);
    LightIlluminateSample s;
    ASSERT_TRUE(light.illuminate(ref, Vec2(0.3f, 0.7f), s));
    EXPECT_NEAR(s.wi.z, 1.0f, 1e-6f);
    EXPECT_FLOAT_EQ(s.distance, 3.0f);
    EXPECT_EQ(s.radiance, Rgb(4, 5, 6));
    EXPECT_FLOAT_EQ(s.pdf_direct_w, 9.0f);  // radiance / pdf_direct_w = I / d^2
    EXPECT_FLOAT_EQ(s.pdf_emission_w, kInv4Pi);
    EXPECT_FLOAT_EQ(s.cos_at_light, 1.0f);
    // A receiver on the light has no direction to it.
    EXPECT_FALSE(light.illuminate(Vec3(1, 2, 3), Vec2(0.5f, 0.5f), s));
    EXPECT_TRUE(light.radiance(Vec3(1, 2, 3), Vec3(0, 0, 1), Vec3(0, 0, -1)).radiance.is_black());
    expect_close(light.power(), Rgb(4, 5, 6) * (4.0f * kPi));
    EXPECT_TRUE(light.is_delta());
    EXPECT_TRUE(light.is_finite());
}

TEST(PointLight, IrradianceIsInverseSquare) {
    PointLight light(Vec3(0, 0, 2), Rgb(3));
    Vec3 n = normalize(Vec3(0.3f, 0, 1));
    Vec3 p(1, 0, 0);
    double d2 = 5.0, cos = dot(normalize(Vec3(-1, 0, 2)), n);
    // Zero variance: every sample is exact, so the tolerance is float round-off.
    Estimate e = irradiance(light, p, n, 1000, 1);
    EXPECT_NEAR(e.mean, 3.0 * cos / d2, 1e-6);
}

TEST(PointLight, EmitIsUniformAndAgreesWithIlluminate) {
    PointLight light(Vec3(1, 2, 3), Rgb(2));
    auto sample = [&](Rng& rng) -> std::optional<Vec3> {
        LightEmitSample s;
        if (!light.emit(rng.next_2d(), rng.next_2d(), s)) return std::nullopt;
        return s.direction;
    };
    ChiSquareResult r = chi_square_test_sphere(
        sample, [](const Vec3&) { return double(kInv4Pi); }, chi_options());
    EXPECT_TRUE(r.passed) << r.message;

    LightEmitSample e;
    ASSERT_TRUE(light.emit(Vec2(0.1f, 0.2f), Vec2(0.3f, 0.4f), e));
    EXPECT_EQ(e.origin, Vec3(1, 2, 3));
    EXPECT_EQ(e.energy, Rgb(2));
    EXPECT_FLOAT_EQ(e.pdf_direct_a, 1.0f);
    // Illuminating a point on the emitted ray reports the same emission density.
    LightIlluminateSample s;
    ASSERT_TRUE(light.illuminate(e.origin + e.direction * 2.5f, Vec2(0.5f, 0.5f), s));
    EXPECT_FLOAT_EQ(s.pdf_emission_w, e.pdf_emission_w);
    EXPECT_NEAR(dot(s.wi, e.direction), -1.0f, 1e-5f);
}

// ---------------------------------------------------------------------------------------
// Directional light

TEST(DirectionalLight, IlluminateAndEmit) {
    Vec3 dir = normalize(Vec3(1, -2, 0.5f));
    DirectionalLight light(dir * 3.0f, Rgb(2, 3, 4));
    SceneSphere sphere = test_scene_sphere();
    light.preprocess(sphere);
    float disk_pdf = 1.0f / (kPi * sphere.radius * sphere.radius);

    LightIlluminateSample s;
    ASSERT_TRUE(light.illuminate(Vec3(0, 0, 0), Vec2(0.2f, 0.9f), s));
    EXPECT_NEAR(dot(s.wi, -dir), 1.0f, 1e-6f);
    EXPECT_EQ(s.distance, kInfinity);
    EXPECT_EQ(s.radiance, Rgb(2, 3, 4));
    EXPECT_FLOAT_EQ(s.pdf_direct_w, 1.0f);
    expect_close(s.pdf_emission_w, disk_pdf);

    Rng rng(StreamKey{5, 0, 1, 0});
    Vec3 mean_offset(0.0f);
    const int n = 20000;
    for (int i = 0; i < n; ++i) {
        LightEmitSample e;
        ASSERT_TRUE(light.emit(rng.next_2d(), rng.next_2d(), e));
        EXPECT_NEAR(dot(e.direction, dir), 1.0f, 1e-6f);
        expect_close(e.pdf_emission_w, s.pdf_emission_w);
        EXPECT_FLOAT_EQ(e.pdf_direct_a, 1.0f);
        EXPECT_EQ(e.energy, Rgb(2, 3, 4));
        // The origin lies on the disk of radius R, R behind the centre, facing `dir`.
        Vec3 offset = e.origin - sphere.center;
        EXPECT_NEAR(dot(offset, dir), -sphere.radius, 1e-4f);
        Vec3 lateral = offset - dir * dot(offset, dir);
        EXPECT_LE(length(lateral), sphere.radius * (1 + 1e-5f));
        mean_offset += lateral / float(n);
    }
    EXPECT_LT(length(mean_offset), 0.05f * sphere.radius);  // centred (~3 standard errors)
    expect_close(light.power(), Rgb(2, 3, 4) * (kPi * 9.0f));
    EXPECT_TRUE(light.radiance(Vec3(0.0f), Vec3(0, 0, 1), -dir).radiance.is_black());
    EXPECT_TRUE(light.is_delta());
    EXPECT_FALSE(light.is_finite());
}

TEST(DirectionalLight, IrradianceIsCosineWeighted) {
    DirectionalLight light(Vec3(0, 0, -1), Rgb(2));
    Vec3 n = normalize(Vec3(1, 0, 1));
    EXPECT_NEAR(irradiance(light, Vec3(0.0f), n, 10, 1).mean, 2.0 * std::sqrt(0.5), 1e-6);
}

// ---------------------------------------------------------------------------------------
// Area light

// A 2 x 1 rectangle in the plane z = 1, facing down (-z).
Parallelogram ceiling() {
    return Parallelogram(Vec3(-1, -0.5f, 1), Vec3(0, 1, 0), Vec3(2, 0, 0));
}

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

TEST(AreaLight, IlluminateDirectionsChiSquareSphere) {
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
    ChiSquareResult r = chi_square_test_sphere(sample, pdf, chi_options());
    EXPECT_TRUE(r.passed) << r.message;
    EXPECT_NEAR(r.pdf_integral, 1.0, 1e-3);
}

TEST(AreaLight, IlluminateDirectionsChiSquareRectangle) {
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
    ChiSquareResult r = chi_square_test_2d(sample, pdf, Rect{0, 1, 0, 1}, chi_options());
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

// ---------------------------------------------------------------------------------------
// Constant (uniform background) light

TEST(ConstantLight, SamplingRoutinesAgree) {
    ConstantLight light(Rgb(0.5f, 1, 2));
    SceneSphere sphere = test_scene_sphere();
    light.preprocess(sphere);
    float pdf_e = kInv4Pi / (kPi * sphere.radius * sphere.radius);
    Rng rng(StreamKey{31, 0, 1, 0});
    for (int i = 0; i < 1000; ++i) {
        LightIlluminateSample s;
        ASSERT_TRUE(light.illuminate(Vec3(1, 2, 3), rng.next_2d(), s));
        EXPECT_EQ(s.distance, kInfinity);
        EXPECT_FLOAT_EQ(s.pdf_direct_w, kInv4Pi);
        expect_close(s.pdf_emission_w, pdf_e);
        LightRadiance r = light.radiance(Vec3(0.0f), Vec3(0.0f), s.wi);
        EXPECT_EQ(r.radiance, s.radiance);
        EXPECT_FLOAT_EQ(r.pdf_direct_a, s.pdf_direct_w);
        EXPECT_FLOAT_EQ(r.pdf_emission_w, s.pdf_emission_w);

        LightEmitSample e;
        ASSERT_TRUE(light.emit(rng.next_2d(), rng.next_2d(), e));
        LightRadiance back = light.radiance(Vec3(0.0f), Vec3(0.0f), -e.direction);
        EXPECT_EQ(back.radiance, e.energy);
        EXPECT_FLOAT_EQ(back.pdf_emission_w, e.pdf_emission_w);
        EXPECT_FLOAT_EQ(back.pdf_direct_a, e.pdf_direct_a);
        // Inward rays from the disk R outside the centre.
        Vec3 offset = e.origin - sphere.center;
        EXPECT_NEAR(dot(offset, e.direction), -sphere.radius, 1e-4f);
        EXPECT_LE(length_squared(offset), 2 * sphere.radius * sphere.radius * (1 + 1e-5f));
    }
    expect_close(light.power(), Rgb(0.5f, 1, 2) * (4 * kPi * kPi * 9.0f));
    EXPECT_TRUE(light.is_infinite_background());
    EXPECT_FALSE(light.is_finite());
    EXPECT_FALSE(light.is_delta());
}

TEST(ConstantLight, MonteCarloIrradiance) {
    ConstantLight light(Rgb(3));
    expect_estimate(irradiance(light, Vec3(0.0f), normalize(Vec3(1, 1, 0)), 200000, 32),
                    3.0 * M_PI);
}

// ---------------------------------------------------------------------------------------
// Environment map

// A W x H map whose texel (col, row) has a distinct value, plus a bright texel.
std::vector<Rgb> pattern(int w, int h, float bright) {
    std::vector<Rgb> t(size_t(w * h));
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x)
            t[size_t(y * w + x)] = Rgb(0.1f + x, 0.2f + y, 1.0f + 0.5f * ((x + y) % 3));
    t[size_t(1 * w + 5)] = Rgb(bright, bright * 0.5f, bright * 0.25f);
    return t;
}

Vec2 texel_center(int col, int row, int w, int h) {
    return {(col + 0.5f) / w, (row + 0.5f) / h};
}

TEST(EnvmapLight, LatLongMappingIsMitsubas) {
    // u = atan2(x, -z) / (2 pi) wrapped to [0, 1), v = acos(y) / pi.
    auto uv = [](Vec3 d) { return EnvmapLight::direction_to_uv(d); };
    EXPECT_NEAR(uv(Vec3(0, 0, -1)).x, 0.0f, 1e-6f);
    EXPECT_NEAR(uv(Vec3(1, 0, 0)).x, 0.25f, 1e-6f);
    EXPECT_NEAR(uv(Vec3(0, 0, 1)).x, 0.5f, 1e-6f);
    EXPECT_NEAR(uv(Vec3(-1, 0, 0)).x, 0.75f, 1e-6f);
    EXPECT_NEAR(uv(Vec3(0, 1, 0)).y, 0.0f, 1e-6f);
    EXPECT_NEAR(uv(Vec3(1, 0, 0)).y, 0.5f, 1e-6f);
    EXPECT_GT(uv(Vec3(0, -1, 0)).y, 0.999f);
    EXPECT_LT(uv(Vec3(0, -1, 0)).y, 1.0f);
    // Just left of the seam (-z, from the -x side) wraps to u just below 1, never to 1.
    Vec2 seam = uv(normalize(Vec3(-1e-8f, 0, -1)));
    EXPECT_GE(seam.x, 0.0f);
    EXPECT_LT(seam.x, 1.0f);
    Rng rng(StreamKey{41, 0, 1, 0});
    for (int i = 0; i < 1000; ++i) {
        Vec3 d = warp::square_to_uniform_sphere(rng.next_2d());
        Vec3 back = EnvmapLight::uv_to_direction(uv(d));
        EXPECT_NEAR(length(back - d), 0.0f, 1e-4f) << d;
    }
}

TEST(EnvmapLight, NearestTexelLookup) {
    const int w = 8, h = 4;
    std::vector<Rgb> t = pattern(w, h, 50.0f);
    EnvmapLight light(t, w, h, Frame());
    for (int row = 0; row < h; ++row)
        for (int col = 0; col < w; ++col) {
            Vec3 d = EnvmapLight::uv_to_direction(texel_center(col, row, w, h));
            EXPECT_EQ(light.radiance(Vec3(0.0f), Vec3(0.0f), d).radiance, t[size_t(row * w + col)]);
        }
}

TEST(EnvmapLight, SamplingRoutinesAgree) {
    const int w = 8, h = 4;
    Frame frame = *EnvmapLight::rotation_frame(Transform::rotate(Vec3(1, 2, 3), 40.0f));
    EnvmapLight light(pattern(w, h, 50.0f), w, h, frame);
    SceneSphere sphere = test_scene_sphere();
    light.preprocess(sphere);
    float disk_pdf = 1.0f / (kPi * sphere.radius * sphere.radius);
    Rng rng(StreamKey{42, 0, 1, 0});
    for (int i = 0; i < 5000; ++i) {
        LightIlluminateSample s;
        ASSERT_TRUE(light.illuminate(Vec3(1, 2, 3), rng.next_2d(), s));
        EXPECT_EQ(s.distance, kInfinity);
        LightRadiance r = light.radiance(Vec3(0.0f), Vec3(0.0f), s.wi);
        EXPECT_EQ(r.radiance, s.radiance);
        EXPECT_EQ(r.pdf_direct_a, s.pdf_direct_w);
        EXPECT_EQ(r.pdf_emission_w, s.pdf_emission_w);
        expect_close(s.pdf_emission_w, s.pdf_direct_w * disk_pdf);

        LightEmitSample e;
        ASSERT_TRUE(light.emit(rng.next_2d(), rng.next_2d(), e));
        LightRadiance back = light.radiance(Vec3(0.0f), Vec3(0.0f), -e.direction);
        EXPECT_EQ(back.radiance, e.energy);
        expect_close(back.pdf_emission_w, e.pdf_emission_w);
        expect_close(back.pdf_direct_a, e.pdf_direct_a);
        Vec3 offset = e.origin - sphere.center;
        EXPECT_NEAR(dot(offset, e.direction), -sphere.radius, 1e-4f);
    }
}

// Chi-square statistic of observed counts against exact expected cell probabilities (cells
// with expected count < 5 pooled), p-value from tests/support's regularized_gamma_q.
ChiSquareResult chi_square_exact(const std::vector<double>& observed,
                                 const std::vector<double>& probability, int sample_count) {
    std::vector<size_t> order(observed.size());
    for (size_t i = 0; i < order.size(); ++i) order[i] = i;
    std::sort(order.begin(), order.end(),
              [&](size_t a, size_t b) { return probability[a] < probability[b]; });
    ChiSquareResult r;
    double pooled_o = 0, pooled_e = 0;
    int groups = 0;
    for (size_t i : order) {
        double e = probability[i] * sample_count;
        r.pdf_integral += probability[i];
        if (e == 0) {
            if (observed[i] > 0) {
                r.message = "cell " + std::to_string(i) + " has samples but probability 0";
                return r;
            }
            continue;
        }
        pooled_o += observed[i];
        pooled_e += e;
        if (pooled_e < 5) continue;
        r.statistic += (pooled_o - pooled_e) * (pooled_o - pooled_e) / pooled_e;
        pooled_o = pooled_e = 0;
        ++groups;
    }
    if (pooled_e > 0) {
        r.statistic += (pooled_o - pooled_e) * (pooled_o - pooled_e) / pooled_e;
        ++groups;
    }
    r.degrees_of_freedom = std::max(1, groups - 1);
    r.p_value = regularized_gamma_q(0.5 * r.degrees_of_freedom, 0.5 * r.statistic);
    double alpha = 1.0 - std::pow(1.0 - 0.01, 1.0 / kChiSquareTests);
    r.passed = r.p_value >= alpha;
    r.message = "chi2 = " + std::to_string(r.statistic) +
                ", dof = " + std::to_string(r.degrees_of_freedom) +
                ", p = " + std::to_string(r.p_value) + ", alpha = " + std::to_string(alpha);
    return r;
}

TEST(EnvmapLight, SampledDirectionsChiSquare) {
    // Histogram in the map's own chart (u, v) on cells aligned with the texels (4 x 4 cells
    // per texel). The claimed solid-angle density becomes pdf_w * |d omega / d(u, v)| =
    // pdf_w * 2 pi^2 sin theta there; each cell's probability integrates it with a 4 x 4
    // midpoint rule (no node on a texel edge, where the density jumps; tests/support's
    // Simpson cells would put nodes there). A rotated frame checks that sampling and lookup
    // use the same transform; the bright texel holds most of the mass.
    const int w = 8, h = 4, k = 4, nx = w * k, ny = h * k, samples = 1000000;
    Frame frame = *EnvmapLight::rotation_frame(Transform::rotate(Vec3(-1, 0.5f, 2), 75.0f));
    EnvmapLight light(pattern(w, h, 50.0f), w, h, frame);
    std::vector<double> observed(size_t(nx * ny), 0.0), probability(size_t(nx * ny), 0.0);
    Rng rng(StreamKey{45, 0, 1, 0});
    for (int i = 0; i < samples; ++i) {
        LightIlluminateSample s;
        if (!light.illuminate(Vec3(0.0f), rng.next_2d(), s)) continue;
        Vec2 uv = EnvmapLight::direction_to_uv(frame.to_local(s.wi));
        observed[size_t(std::min(int(uv.y * ny), ny - 1) * nx +
                        std::min(int(uv.x * nx), nx - 1))] += 1;
    }
    const int m = 4;  // midpoint nodes per cell and axis
    for (int y = 0; y < ny; ++y)
        for (int x = 0; x < nx; ++x) {
            double sum = 0;
            for (int i = 0; i < m; ++i)
                for (int j = 0; j < m; ++j) {
                    Vec2 uv((x + (i + 0.5f) / m) / nx, (y + (j + 0.5f) / m) / ny);
                    Vec3 wi = frame.to_world(EnvmapLight::uv_to_direction(uv));
                    sum +=
                        double(light.pdf_direction(wi)) * 2 * M_PI * M_PI * std::sin(M_PI * uv.y);
                }
            probability[size_t(y * nx + x)] = sum / (m * m) / (double(nx) * ny);
        }
    ChiSquareResult r = chi_square_exact(observed, probability, samples);
    EXPECT_TRUE(r.passed) << r.message;
    EXPECT_NEAR(r.pdf_integral, 1.0, 1e-4);
}

TEST(EnvmapLight, MonteCarloIrradianceOfAUniformMap) {
    // A constant map is a constant background: E = pi L whatever the orientation.
    EnvmapLight light(std::vector<Rgb>(16 * 8, Rgb(2)), 16, 8,
                      *EnvmapLight::rotation_frame(Transform::rotate(Vec3(0, 1, 1), 30)));
    for (Vec3 n : {Vec3(0, 1, 0), normalize(Vec3(1, -1, 0.3f))})
        expect_estimate(irradiance(light, Vec3(0.0f), n, 200000, 43), 2.0 * M_PI);
    light.preprocess(test_scene_sphere());
    // power = pi R^2 * 4 pi L
    expect_close(light.power(), Rgb(2 * 4 * kPi * kPi * 9.0f), 1e-4f);
}

TEST(EnvmapLight, ExtremeTexelsStayFinite) {
    const int w = 8, h = 4;
    std::vector<Rgb> t = pattern(w, h, 1e30f);
    t[3] = Rgb(std::numeric_limits<float>::max());
    t[4] = Rgb(kInfinity, std::nanf(""), -1.0f);
    EnvmapLight light(t, w, h, Frame());
    light.preprocess(test_scene_sphere());
    EXPECT_TRUE(light.power().is_finite());
    Rng rng(StreamKey{44, 0, 1, 0});
    int bright = 0;
    for (int i = 0; i < 10000; ++i) {
        LightIlluminateSample s;
        if (light.illuminate(Vec3(0.0f), rng.next_2d(), s)) {
            ASSERT_TRUE(s.radiance.is_finite() && is_finite(s.wi));
            ASSERT_TRUE(std::isfinite(s.pdf_direct_w) && s.pdf_direct_w > 0);
            ASSERT_TRUE(std::isfinite(s.pdf_emission_w));
            bright += s.radiance.r >= 1e30f;
        }
        LightEmitSample e;
        if (light.emit(rng.next_2d(), rng.next_2d(), e)) {
            ASSERT_TRUE(e.energy.is_finite() && std::isfinite(e.pdf_emission_w) &&
                        is_finite(e.origin) && is_finite(e.direction));
        }
    }
    EXPECT_GT(bright, 0);
    // The non-finite texel reads as black.
    Vec3 d = EnvmapLight::uv_to_direction(texel_center(4, 0, w, h));
    EXPECT_EQ(light.radiance(Vec3(0.0f), Vec3(0.0f), d).radiance, Rgb(0.0f));
    // Poles and axes: finite radiance, finite (at the poles: zero) density.
    for (Vec3 a : {Vec3(0, 1, 0), Vec3(0, -1, 0), Vec3(1, 0, 0), Vec3(0, 0, -1), Vec3(0, 0, 1)}) {
        LightRadiance r = light.radiance(Vec3(0.0f), Vec3(0.0f), a);
        EXPECT_TRUE(r.radiance.is_finite());
        EXPECT_TRUE(std::isfinite(r.pdf_direct_a) && std::isfinite(r.pdf_emission_w));
    }
    // A black map samples nothing.
    EnvmapLight black(std::vector<Rgb>(8, Rgb(0.0f)), 4, 2, Frame());
    LightIlluminateSample s;
    EXPECT_FALSE(black.illuminate(Vec3(0.0f), Vec2(0.5f, 0.5f), s));
    EXPECT_EQ(black.power(), Rgb(0.0f));
}

// ---------------------------------------------------------------------------------------
// Factory

struct TempDir {
    std::filesystem::path path;
    TempDir() {
        path =
            std::filesystem::temp_directory_path() / ("light_test_" + std::to_string(::getpid()));
        std::filesystem::create_directories(path);
    }
    ~TempDir() {
        std::error_code ec;
        std::filesystem::remove_all(path, ec);
    }
};

void write_exr(const std::filesystem::path& file, const std::vector<Rgb>& texels, int w, int h) {
    auto out = OIIO::ImageOutput::create(file.string());
    ASSERT_TRUE(out) << OIIO::geterror();
    OIIO::ImageSpec spec(w, h, 3, OIIO::TypeDesc::FLOAT);
    ASSERT_TRUE(out->open(file.string(), spec)) << out->geterror();
    ASSERT_TRUE(out->write_image(OIIO::TypeDesc::FLOAT, texels.data())) << out->geterror();
    out->close();
}

SourceLocation at(int line) {
    return SourceLocation{"scene.xml", line};
}

std::string factory_error(const Properties& props, const Shape* shape = nullptr,
                          const std::filesystem::path& dir = ".") {
    try {
        make_light(props, shape, dir);
    } catch (const SceneError& e) {
        return e.what();
    }
    return "(no error)";
}

TEST(LightFactory, BuildsEveryType) {
    Parallelogram shape = ceiling();
    Properties area("emitter", "area", at(3));
    area.set("radiance", Rgb(1, 2, 3), at(4));
    auto a = make_light(area, &shape, ".");
    EXPECT_NE(dynamic_cast<AreaLight*>(a.get()), nullptr);
    area.check_all_used();

    Properties point("emitter", "point", at(5));
    point.set("to_world", Transform::translate(Vec3(1, 2, 3)), at(6));
    point.set("intensity", Rgb(7), at(7));
    auto p = make_light(point, nullptr, ".");
    ASSERT_NE(dynamic_cast<PointLight*>(p.get()), nullptr);
    EXPECT_EQ(dynamic_cast<PointLight*>(p.get())->position(), Vec3(1, 2, 3));
    point.check_all_used();

    Properties directional("emitter", "directional", at(8));
    directional.set("to_world", Transform::rotate(Vec3(1, 0, 0), 90), at(9));
    directional.set("irradiance", 2.0f, at(10));
    auto d = make_light(directional, nullptr, ".");
    ASSERT_NE(dynamic_cast<DirectionalLight*>(d.get()), nullptr);
    // +z rotated by 90 degrees about +x is -y.
    EXPECT_NEAR(dynamic_cast<DirectionalLight*>(d.get())->direction().y, -1.0f, 1e-6f);
    directional.check_all_used();

    Properties constant("emitter", "constant", at(11));
    constant.set("radiance", Rgb(0.5f), at(12));
    auto c = make_light(constant, nullptr, ".");
    EXPECT_TRUE(c->is_infinite_background());
    constant.check_all_used();
}

TEST(LightFactory, LoadsAnEnvmapFromAnExrFile) {
    TempDir dir;
    const int w = 8, h = 4;
    std::vector<Rgb> t = pattern(w, h, 1e6f);
    write_exr(dir.path / "sky.exr", t, w, h);
    Properties props("emitter", "envmap", at(20));
    props.set("filename", std::string("sky.exr"), at(21));  // relative to the scene folder
    props.set("scale", 2.0f, at(22));
    props.set("to_world", Transform::rotate(Vec3(0, 1, 0), 90), at(23));
    auto light = make_light(props, nullptr, dir.path);
    props.check_all_used();
    auto* env = dynamic_cast<EnvmapLight*>(light.get());
    ASSERT_NE(env, nullptr);
    EXPECT_EQ(env->width(), w);
    EXPECT_EQ(env->height(), h);
    Frame frame = *EnvmapLight::rotation_frame(Transform::rotate(Vec3(0, 1, 0), 90));
    for (int row = 0; row < h; ++row)
        for (int col = 0; col < w; ++col) {
            Vec3 d = frame.to_world(EnvmapLight::uv_to_direction(texel_center(col, row, w, h)));
            expect_close(env->radiance(Vec3(0.0f), Vec3(0.0f), d).radiance,
                         t[size_t(row * w + col)] * 2.0f);
        }
}

TEST(LightFactory, LoadsAnSrgbPngAsLinear) {
    TempDir dir;
    const std::string file = (dir.path / "sky.png").string();
    {
        auto out = OIIO::ImageOutput::create(file);
        ASSERT_TRUE(out);
        OIIO::ImageSpec spec(2, 1, 3, OIIO::TypeDesc::UINT8);
        ASSERT_TRUE(out->open(file, spec));
        const unsigned char pixels[6] = {128, 128, 128, 255, 0, 255};
        ASSERT_TRUE(out->write_image(OIIO::TypeDesc::UINT8, pixels));
        out->close();
    }
    Properties props("emitter", "envmap", at(40));
    props.set("filename", file, at(41));
    auto light = make_light(props, nullptr, "/unused");
    // u in [0, 1/2) is the left pixel: sRGB 128/255 decodes to 0.2158.
    Vec3 left = EnvmapLight::uv_to_direction(Vec2(0.25f, 0.5f));
    Vec3 right = EnvmapLight::uv_to_direction(Vec2(0.75f, 0.5f));
    expect_close(light->radiance(Vec3(0.0f), Vec3(0.0f), left).radiance, Rgb(0.21586f), 1e-3f);
    EXPECT_EQ(light->radiance(Vec3(0.0f), Vec3(0.0f), right).radiance, Rgb(1, 0, 1));
}

TEST(LightFactory, ErrorMessages) {
    Properties unknown("emitter", "spot", at(12));
    EXPECT_EQ(factory_error(unknown),
              "scene.xml:12: unknown emitter type \"spot\" (supported: area, point, "
              "directional, constant, envmap)");

    Properties area("emitter", "area", at(13));
    EXPECT_NE(factory_error(area).find("scene.xml:13: emitter \"area\" must be nested inside a "
                                       "shape"),
              std::string::npos)
        << factory_error(area);

    Parallelogram shape = ceiling();
    Properties nested("emitter", "point", at(14));
    EXPECT_NE(factory_error(nested, &shape).find("cannot be nested"), std::string::npos);

    Properties negative("emitter", "area", at(15));
    negative.set("radiance", Rgb(1, -2, 3), at(16));
    std::string message = factory_error(negative, &shape);
    EXPECT_NE(message.find("scene.xml:16"), std::string::npos) << message;
    EXPECT_NE(message.find("\"radiance\""), std::string::npos) << message;
    EXPECT_NE(message.find("non-negative"), std::string::npos) << message;

    Properties nan("emitter", "point", at(17));
    nan.set("intensity", Rgb(std::nanf("")), at(18));
    EXPECT_NE(factory_error(nan).find("scene.xml:18"), std::string::npos);

    Properties both("emitter", "point", at(19));
    both.set("position", Vec3(0.0f), at(20));
    both.set("to_world", Transform(), at(21));
    EXPECT_NE(factory_error(both).find("not both"), std::string::npos);

    Properties zero("emitter", "directional", at(22));
    zero.set("direction", Vec3(0.0f), at(23));
    EXPECT_NE(factory_error(zero).find("scene.xml:23"), std::string::npos);
}

TEST(LightFactory, EnvmapFileErrors) {
    TempDir dir;
    Properties missing("emitter", "envmap", at(30));
    missing.set("filename", std::string("textures/nothere.exr"), at(31));
    std::string message = factory_error(missing, nullptr, dir.path);
    EXPECT_NE(message.find("scene.xml:31"), std::string::npos) << message;
    EXPECT_NE(message.find((dir.path / "textures/nothere.exr").string()), std::string::npos)
        << message;
    EXPECT_NE(message.find("not found"), std::string::npos) << message;

    {
        std::ofstream garbage(dir.path / "bad.exr");
        garbage << "this is not an image";
    }
    Properties bad("emitter", "envmap", at(32));
    bad.set("filename", (dir.path / "bad.exr").string(), at(33));
    message = factory_error(bad, nullptr, "/elsewhere");
    EXPECT_NE(message.find("scene.xml:33"), std::string::npos) << message;
    EXPECT_NE(message.find("cannot read environment map \"" + (dir.path / "bad.exr").string()),
              std::string::npos)
        << message;

    write_exr(dir.path / "ok.exr", std::vector<Rgb>(8, Rgb(1.0f)), 4, 2);
    Properties skew("emitter", "envmap", at(34));
    skew.set("filename", std::string("ok.exr"), at(35));
    skew.set("to_world", Transform::scale(Vec3(1, 2, 1)), at(36));
    message = factory_error(skew, nullptr, dir.path);
    EXPECT_NE(message.find("scene.xml:36"), std::string::npos) << message;
    EXPECT_NE(message.find("rotation"), std::string::npos) << message;

    Properties scale("emitter", "envmap", at(37));
    scale.set("filename", std::string("ok.exr"), at(38));
    scale.set("scale", -1.0f, at(39));
    EXPECT_NE(factory_error(scale, nullptr, dir.path).find("scene.xml:39"), std::string::npos);
}

}  // namespace
}  // namespace render::testing
