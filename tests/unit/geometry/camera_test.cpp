#include <gtest/gtest.h>

#include <cmath>

#include "core/camera/perspective_camera.h"
#include "core/math/constants.h"
#include "core/sampling/rng.h"
#include "core/sampling/warp.h"
#include "tests/support/statistics.h"

namespace render {
namespace {

PerspectiveCamera test_camera(int w = 64, int h = 48, char axis = 'x') {
    Transform to_world = Transform::look_at(Vec3(1, 2, 3), Vec3(0, 0, 0), Vec3(0, 1, 0));
    return PerspectiveCamera(to_world, 40.0f, axis, w, h);
}

TEST(PerspectiveCamera, RasterPositionInvertsGenerateRay) {
    PerspectiveCamera camera = test_camera();
    Rng rng(StreamKey{7, 0, 1, 0});
    for (int i = 0; i < 1000; ++i) {
        Vec2 raster(rng.next_1d() * 64, rng.next_1d() * 48);
        Ray ray = camera.generate_ray(raster);
        auto back = camera.raster_position(ray.at(2.5f));
        ASSERT_TRUE(back.has_value());
        EXPECT_NEAR(back->x, raster.x, 1e-3);
        EXPECT_NEAR(back->y, raster.y, 1e-3);
    }
    // Behind the camera there is no raster position.
    EXPECT_FALSE(camera.raster_position(camera.position() - camera.forward()).has_value());
}

TEST(PerspectiveCamera, MitsubaOrientation) {
    // Mitsuba's camera: +x of camera space is the image's left, +y is up.
    PerspectiveCamera camera(Transform(), 90.0f, 'x', 100, 100);
    Ray left = camera.generate_ray(Vec2(0, 50));
    Ray top = camera.generate_ray(Vec2(50, 0));
    EXPECT_GT(left.direction.x, 0.5f);
    EXPECT_GT(top.direction.y, 0.5f);
    Ray center = camera.generate_ray(Vec2(50, 50));
    EXPECT_NEAR(center.direction.z, 1.0f, 1e-6);
    // fov 90 along x: the left edge is at 45 degrees.
    EXPECT_NEAR(left.direction.x, std::sqrt(0.5f), 1e-5);
}

TEST(PerspectiveCamera, FovAxisY) {
    PerspectiveCamera camera(Transform(), 90.0f, 'y', 200, 100);
    Ray top = camera.generate_ray(Vec2(100, 0));
    EXPECT_NEAR(top.direction.y, std::sqrt(0.5f), 1e-5);
    Ray left = camera.generate_ray(Vec2(0, 50));
    EXPECT_NEAR(left.direction.x / left.direction.z, 2.0f, 1e-5);
}

TEST(PerspectiveCamera, FovAxisDiagonalKeepsTheDiagonal) {
    // fov 90 along the diagonal: the corner ray is at 45 degrees, whatever the image's shape
    // (a focal length maps to such a diagonal fov, as in Mitsuba).
    for (auto [w, h] : {std::pair{300, 200}, std::pair{100, 100}, std::pair{50, 400}}) {
        PerspectiveCamera camera =
            PerspectiveCamera(Transform(), 90.0f, 'd', 64, 64).with_resolution(w, h);
        Ray corner = camera.generate_ray(Vec2(0, 0));
        EXPECT_NEAR(corner.direction.z, std::sqrt(0.5f), 1e-5) << w << "x" << h;
        // Pixels stay square: the horizontal and vertical extents keep the aspect ratio.
        Ray left = camera.generate_ray(Vec2(0, h / 2.0f));
        Ray top = camera.generate_ray(Vec2(w / 2.0f, 0));
        EXPECT_NEAR((left.direction.x / left.direction.z) / (top.direction.y / top.direction.z),
                    float(w) / float(h), 1e-4);
    }
}

TEST(PerspectiveCamera, DirectionPdfIntegratesToOne) {
    // Monte Carlo over the sphere of directions: E[pdf / uniform_pdf] = 1. With 2e6 samples the
    // standard error is below 3e-3 for this camera; the tolerance is 5 standard errors.
    PerspectiveCamera camera = test_camera();
    Rng rng(StreamKey{3, 0, 1, 0});
    const int n = 2000000;
    testing::MeanAccumulator ratio;
    for (int i = 0; i < n; ++i) {
        Vec3 d = warp::square_to_uniform_sphere(rng.next_2d());
        ratio.add(camera.direction_pdf_w(d) / warp::square_to_uniform_sphere_pdf());
    }
    EXPECT_NEAR(ratio.mean(), 1.0, 5 * ratio.standard_error())
        << "standard error " << ratio.standard_error();
}

TEST(PerspectiveCamera, DirectionPdfMatchesRasterDensity) {
    // The density of generate_ray directions for uniform raster positions, measured by the
    // Jacobian of the raster-to-direction map with finite differences.
    PerspectiveCamera camera = test_camera();
    const float h = 1e-2f;
    for (Vec2 raster : {Vec2(32, 24), Vec2(3, 5), Vec2(60, 40)}) {
        Vec3 d = camera.generate_ray(raster).direction;
        Vec3 dx = camera.generate_ray(raster + Vec2(h, 0)).direction - d;
        Vec3 dy = camera.generate_ray(raster + Vec2(0, h)).direction - d;
        double solid_angle_per_pixel = length(cross(dx, dy)) / (h * h);
        double expected = 1.0 / (solid_angle_per_pixel * 64 * 48);
        EXPECT_NEAR(camera.direction_pdf_w(d), expected, 2e-3 * expected);
    }
}

TEST(PerspectiveCamera, WithResolutionKeepsHorizontalFov) {
    PerspectiveCamera camera = test_camera(64, 48);
    PerspectiveCamera wide = camera.with_resolution(128, 48);
    EXPECT_EQ(wide.width(), 128);
    Vec3 a = camera.generate_ray(Vec2(0, 24)).direction;
    Vec3 b = wide.generate_ray(Vec2(0, 24)).direction;
    EXPECT_NEAR(dot(a, b), 1.0f, 1e-6);
}

}  // namespace
}  // namespace render
