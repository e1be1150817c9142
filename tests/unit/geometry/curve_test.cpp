// Curves (core/shapes/curve.h, core/shapes/curve_input.h): the exact conversions of every basis
// and degree to cubic Bezier segments; hits on flat, cylinder and ribbon curves against the
// hand-computed tube and ribbon (distance, normal, u, and the offset h = 2 v - 1 the hair BSDF
// reads); rays leaving a curve pass through it but still hit the next one; cut-outs; the
// Mitsuba curve file.

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <memory>

#include "core/base/error.h"
#include "core/scene/scene.h"
#include "core/shapes/alpha_cutout.h"
#include "core/shapes/curve.h"
#include "core/shapes/curve_input.h"
#include "tests/support/temp_dir.h"

namespace render {
namespace {

std::unique_ptr<Scene> scene_with(std::vector<std::unique_ptr<Shape>> shapes) {
    auto scene = std::make_unique<Scene>();
    scene->set_camera(PerspectiveCamera(Transform(), 45, 'x', 4, 4));
    for (auto& s : shapes) scene->add_shape(std::move(s), nullptr);
    scene->commit();
    return scene;
}

// A straight curve along x from x0 to x1 at height z, radius r, as one cubic Bezier segment
// with evenly spaced points (so u is linear in x).
std::unique_ptr<Curves> straight(CurveType type, float z, float r, float x0 = -1, float x1 = 1) {
    const std::vector<Vec3> points = {Vec3(x0, 0, z), Vec3(x0 + (x1 - x0) / 3, 0, z),
                                      Vec3(x0 + 2 * (x1 - x0) / 3, 0, z), Vec3(x1, 0, z)};
    const std::vector<Vec3> normals = {Vec3(0, 0, 1), Vec3(0, 0, 1)};
    return std::make_unique<Curves>(
        pbrt_curve_segments(points, CurveBasis::Bezier, 3, 2 * r, 2 * r,
                            type == CurveType::Ribbon ? normals : std::vector<Vec3>{}, "test"),
        type, "straight");
}

float uniform_bspline(const std::vector<float>& p, int degree, float t_global) {
    // Direct evaluation of a uniform B-spline with the Cox-de Boor recursion on knots 0, 1, ...
    const int n = int(p.size());
    const float x = t_global + float(degree);  // the valid range starts at knot `degree`
    std::vector<float> basis(size_t(n + degree), 0.0f);
    for (int i = 0; i < n + degree; ++i)
        basis[size_t(i)] = (x >= float(i) && x < float(i + 1)) ? 1 : 0;
    for (int d = 1; d <= degree; ++d)
        for (int i = 0; i + d < n + degree; ++i)
            basis[size_t(i)] = (x - float(i)) / float(d) * basis[size_t(i)] +
                               (float(i + d + 1) - x) / float(d) * basis[size_t(i + 1)];
    float sum = 0;
    for (int i = 0; i < n; ++i) sum += basis[size_t(i)] * p[size_t(i)];
    return sum;
}

TEST(CurveInput, BsplinesBecomeTheSameCurveAsBezierSegments) {
    const std::vector<float> values = {0.3f, -1.2f, 2.0f, 0.7f, 1.5f, -0.4f};
    for (int degree : {1, 2, 3}) {
        SCOPED_TRACE(degree);
        const auto cubic = bspline_to_cubic(values, degree);
        ASSERT_EQ(cubic.size(), values.size() - size_t(degree));
        for (size_t s = 0; s < cubic.size(); ++s)
            for (float t : {0.0f, 0.25f, 0.5f, 0.9f})
                EXPECT_NEAR(bezier_value(cubic[s], t),
                            uniform_bspline(values, degree, float(s) + t), 1e-5f);
    }
}

TEST(CurveInput, QuadraticBezierIsElevatedExactly) {
    const std::vector<Vec3> p = {Vec3(0, 0, 0), Vec3(1, 2, 0), Vec3(2, 0, 1), Vec3(3, -1, 1),
                                 Vec3(4, 0, 0)};
    const auto cubic = bezier_to_cubic(p, 2);
    ASSERT_EQ(cubic.size(), 2u);
    for (size_t s = 0; s < 2; ++s)
        for (float t : {0.0f, 0.3f, 0.7f, 1.0f}) {
            const Vec3 &a = p[2 * s], &b = p[2 * s + 1], &c = p[2 * s + 2];
            const Vec3 expected = a * ((1 - t) * (1 - t)) + b * (2 * (1 - t) * t) + c * (t * t);
            const Vec3 got = bezier_point(cubic[s], t);
            EXPECT_NEAR(length(got - expected), 0.0f, 1e-5f);
        }
    // pbrt-v4's counts: 2n + 1 points for degree 2; widths vary linearly over the curve.
    EXPECT_THROW(
        pbrt_curve_segments({p[0], p[1], p[2], p[3]}, CurveBasis::Bezier, 2, 1, 1, {}, "c"),
        SceneError);
    const auto segments = pbrt_curve_segments(p, CurveBasis::Bezier, 2, 0.2f, 0.6f, {}, "c");
    ASSERT_EQ(segments.size(), 2u);
    EXPECT_NEAR(bezier_value(segments[1].radius, 0.5f), 0.5f * (0.2f + 0.4f * 0.75f), 1e-6f);
    EXPECT_FLOAT_EQ(segments[1].u0, 0.5f);
    // Ribbons need one normal per segment end.
    EXPECT_THROW(pbrt_curve_segments(p, CurveBasis::Bezier, 2, 1, 1, {Vec3(0, 0, 1)}, "c"),
                 SceneError);
}

// Rays down -z at offset y across a curve along x: the tube's surface at z = sqrt(r^2 - y^2),
// normal (0, y, z) / r; a flat curve or a ribbon facing +z at z = 0. Every kind reports
// h = y / r (hair.h's convention) and u = (x + 1) / 2.
TEST(Curves, HitsReportDistanceNormalUAndH) {
    const float r = 0.1f;
    for (CurveType type : {CurveType::Flat, CurveType::Cylinder, CurveType::Ribbon}) {
        SCOPED_TRACE(int(type));
        std::vector<std::unique_ptr<Shape>> shapes;
        shapes.push_back(straight(type, 0, r));
        auto scene = scene_with(std::move(shapes));
        for (float y : {-0.09f, -0.05f, 0.0f, 0.03f, 0.08f})
            for (float x : {-0.5f, 0.2f}) {
                SurfaceInteraction si;
                ASSERT_TRUE(
                    scene->intersect(Ray(Vec3(x, y, 5), Vec3(0, 0, -1)), si, HitDetail::kWithUv))
                    << x << " " << y;
                const float z = type == CurveType::Cylinder ? std::sqrt(r * r - y * y) : 0.0f;
                EXPECT_NEAR(si.t, 5 - z, 2e-3f);
                if (type == CurveType::Cylinder) {
                    EXPECT_NEAR(si.geometric_normal.y, y / r, 2e-2f);
                    EXPECT_NEAR(si.geometric_normal.z, z / r, 2e-2f);
                } else {
                    EXPECT_NEAR(std::abs(si.geometric_normal.z), 1.0f, 1e-4f);
                }
                EXPECT_NEAR(si.uv.x, (x + 1) / 2, 2e-3f);
                EXPECT_NEAR(2 * si.uv.y - 1, y / r, 2e-2f);
                // The shading frame runs along the curve (the hair BSDF's x axis).
                EXPECT_NEAR(std::abs(si.shading.s.x), 1.0f, 1e-4f);
                EXPECT_NEAR(dot(si.shading.n, si.geometric_normal), 1.0f, 1e-5f);
            }
        SurfaceInteraction si;
        EXPECT_FALSE(scene->intersect(Ray(Vec3(0, 0.12f, 5), Vec3(0, 0, -1)), si));
        EXPECT_FALSE(scene->intersect(Ray(Vec3(1.2f, 0, 5), Vec3(0, 0, -1)), si));
    }
}

// A ray leaving a curve's surface (spawned from its hit) does not hit the same curve again, in
// any direction, but does hit a second curve below it.
TEST(Curves, RaysLeavingACurvePassThroughItButHitTheNext) {
    for (CurveType type : {CurveType::Flat, CurveType::Cylinder, CurveType::Ribbon}) {
        SCOPED_TRACE(int(type));
        std::vector<std::unique_ptr<Shape>> shapes;
        shapes.push_back(straight(type, 0, 0.1f));
        shapes.push_back(straight(type, -1, 0.1f, -3, 3));
        auto scene = scene_with(std::move(shapes));
        SurfaceInteraction si;
        ASSERT_TRUE(scene->intersect(Ray(Vec3(0.1f, 0.04f, 5), Vec3(0, 0, -1)), si));
        for (const Vec3& d : {Vec3(0, 0, -1), normalize(Vec3(0.3f, -0.04f, -1)), Vec3(0, 0, 1),
                              normalize(Vec3(1, 0.3f, 0.2f))}) {
            const Ray leaving = scene->spawn_ray(si.p, si.geometric_normal, d);
            SurfaceInteraction next;
            const bool hit = scene->intersect(leaving, next);
            if (d.z < -0.5f) {
                ASSERT_TRUE(hit) << d;
                EXPECT_NEAR(next.p.z, -1.0f, 0.11f) << d;  // the second curve
            } else {
                EXPECT_FALSE(hit) << d << " hit at " << next.p;
            }
        }
    }
}

TEST(Curves, CutOutRemovesTheCurveForEveryRay) {
    std::vector<std::unique_ptr<Shape>> shapes;
    auto curve = straight(CurveType::Cylinder, 0, 0.1f);
    curve->alpha = std::make_shared<AlphaCutout>(FloatParam{0.0f, nullptr});
    shapes.push_back(std::move(curve));
    auto scene = scene_with(std::move(shapes));
    SurfaceInteraction si;
    EXPECT_FALSE(scene->intersect(Ray(Vec3(0, 0, 5), Vec3(0, 0, -1)), si));
    EXPECT_FALSE(scene->occluded(Ray(Vec3(0, 0, 5), Vec3(0, 0, -1), 0, 10)));
}

TEST(Curves, AreaAndBounds) {
    const auto tube = straight(CurveType::Cylinder, 0, 0.1f);
    EXPECT_NEAR(tube->surface_area(), 2.0f * 2 * 3.14159265f * 0.1f, 1e-4f);
    const auto flat = straight(CurveType::Flat, 0, 0.1f);
    EXPECT_NEAR(flat->surface_area(), 2.0f * 2 * 2 * 0.1f, 1e-4f);  // both sides of width 2r
    const Aabb b = tube->bounds();
    EXPECT_LE(b.lo.x, -1.1f + 1e-6f);
    EXPECT_GE(b.hi.y, 0.1f - 1e-6f);
}

TEST(CurveInput, ReadsMitsubaCurveFiles) {
    const auto path = testing::fresh_temp_dir("curve_test", "file") / "curves.txt";
    {
        std::ofstream out(path);
        out << "0 0 0 0.1\n1 0 0 0.1\n2 0 0 0.2\n3 0 0 0.2\n4 1 0 0.1\n\n"
            << "# a comment\n0 1 0 0.05\n1 1 0 0.05\n";
    }
    const auto curves = read_curve_file(path);
    ASSERT_EQ(curves.size(), 2u);
    EXPECT_EQ(curves[0].points.size(), 5u);
    EXPECT_EQ(curves[1].radii[1], 0.05f);
    // linearcurve: 4 + 1 segments; bsplinecurve refuses the two-point curve.
    EXPECT_EQ(mitsuba_curve_segments(curves, false, "c").size(), 5u);
    EXPECT_THROW(mitsuba_curve_segments(curves, true, "c"), SceneError);
    {
        std::ofstream out(path);
        out << "0 0 0\n";
    }
    EXPECT_THROW(read_curve_file(path), SceneError);
}

}  // namespace
}  // namespace render
