#pragma once

// Shared fixtures of the light tests (tests/unit/lights/): analytic test-only shapes
// whose exact geometry the tests know, a Monte Carlo irradiance estimator with its standard
// error, relative comparisons, and an environment-map texel pattern.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "core/base/shape.h"
#include "core/lights/light.h"
#include "core/math/constants.h"
#include "core/sampling/rng.h"
#include "core/sampling/warp.h"
#include "tests/support/statistics.h"

namespace render::testing {

// Relative comparison for densities and radiance values.
inline void expect_close(float a, float b, float rel = 1e-4f) {
    EXPECT_NEAR(a, b, rel * std::max(std::abs(a), std::abs(b))) << a << " vs " << b;
}
inline void expect_close(const Rgb& a, const Rgb& b, float rel = 1e-5f) {
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
    void fill_interaction(const Ray&, float, unsigned, float, float, HitDetail,
                          SurfaceInteraction&) const override {}
    Aabb bounds() const override {
        Aabb b;
        for (Vec3 p : {p0_, p0_ + e1_, p0_ + e2_, p0_ + e1_ + e2_}) b.expand(p);
        return b;
    }
    float surface_area() const override { return area_; }
    ShapeSample sample_area(Vec2 u) const override {
        return {p0_ + e1_ * u.x + e2_ * u.y, n_, area_ > 0 ? 1.0f / area_ : 0.0f, u};
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
    void fill_interaction(const Ray&, float, unsigned, float, float, HitDetail,
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
        return {c_ + d * r_, inward_ ? -d : d, 1.0f / surface_area(), Vec2(0.0f, 0.0f)};
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

inline SceneSphere test_scene_sphere() {
    return SceneSphere{Vec3(0.5f, -1.0f, 2.0f), 3.0f};
}

// Mean and standard error of a Monte Carlo estimator of irradiance at `p` with normal `n`
// from illuminate() (contribution = radiance * cos / pdf_direct_w, zero when it fails).
inline MeanEstimate irradiance(const Light& light, const Vec3& p, const Vec3& n, int samples,
                               uint64_t seed) {
    Rng rng(StreamKey{seed, 0, 1, 0});
    MeanAccumulator estimate;
    for (int i = 0; i < samples; ++i) {
        LightIlluminateSample s;
        double f = 0;
        if (light.illuminate(p, rng.next_2d(), s))
            f = double(s.radiance.r) * std::max(0.0f, dot(s.wi, n)) / double(s.pdf_direct_w);
        estimate.add(f);
    }
    return estimate.estimate();
}

// The estimate lies within k standard errors of the reference (plus float round-off).
constexpr double kStandardErrors = 5.0;
inline void expect_estimate(const MeanEstimate& e, double reference) {
    EXPECT_NEAR(e.mean, reference, kStandardErrors * e.standard_error + 1e-5 * reference)
        << "standard error " << e.standard_error;
}

// ---------------------------------------------------------------------------------------
// Area-light and environment-map inputs (also used by the factory tests)

// A 2 x 1 rectangle in the plane z = 1, facing down (-z).
inline Parallelogram ceiling() {
    return Parallelogram(Vec3(-1, -0.5f, 1), Vec3(0, 1, 0), Vec3(2, 0, 0));
}

// A W x H map whose texel (col, row) has a distinct value, plus a bright texel.
inline std::vector<Rgb> pattern(int w, int h, float bright) {
    std::vector<Rgb> t(size_t(w * h));
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x)
            t[size_t(y * w + x)] = Rgb(0.1f + x, 0.2f + y, 1.0f + 0.5f * ((x + y) % 3));
    t[size_t(1 * w + 5)] = Rgb(bright, bright * 0.5f, bright * 0.25f);
    return t;
}

inline Vec2 texel_center(int col, int row, int w, int h) {
    return {(col + 0.5f) / w, (row + 0.5f) / h};
}

}  // namespace render::testing
