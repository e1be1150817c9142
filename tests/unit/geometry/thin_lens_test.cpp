// The thin-lens camera (core/camera/perspective_camera.h):
//   - every ray of a raster position passes through the same focus-plane point, the pinhole
//     ray's, whatever its lens point;
//   - connect() inverts generate_ray: the lens point of u_lens and the raster position of a
//     point on that ray;
//   - chi-square: lens points are uniform on the disk; from a fixed lens point the directions of
//     uniformly drawn raster positions follow direction_pdf_w(lens point, direction);
//   - without a lens every entry point is the pinhole's, bit for bit.

#include <gtest/gtest.h>

#include <cmath>

#include "core/camera/perspective_camera.h"
#include "core/math/constants.h"
#include "core/sampling/rng.h"
#include "tests/support/chi_square.h"

namespace render {
namespace {

using testing::ChiSquareFamily;
using testing::ChiSquareOptions;
using testing::ChiSquareResult;

ChiSquareFamily family;

constexpr float kLensRadius = 0.3f, kFocus = 4.0f;

PerspectiveCamera lens_camera(const Transform& to_world) {
    PerspectiveCamera camera(to_world, 50.0f, 'x', 64, 48);
    camera.set_thin_lens(kLensRadius, kFocus);
    return camera;
}

Transform look_at() {
    return Transform::look_at(Vec3(1, 2, 3), Vec3(0, 0, 0), Vec3(0, 1, 0));
}

TEST(ThinLens, RaysOfOneRasterPositionMeetOnTheFocusPlane) {
    const PerspectiveCamera camera = lens_camera(look_at());
    PerspectiveCamera pinhole(look_at(), 50.0f, 'x', 64, 48);
    Rng rng(StreamKey{3, 0, 0, 0});
    for (int i = 0; i < 500; ++i) {
        const Vec2 raster(rng.next_1d() * 64, rng.next_1d() * 48);
        const Ray center = pinhole.generate_ray(raster);
        // The pinhole ray reaches the focus plane at distance kFocus / cos along it.
        const float cos_theta = dot(center.direction, pinhole.forward());
        const Vec3 focus = center.at(kFocus / cos_theta);
        const Ray ray = camera.generate_ray(raster, rng.next_2d());
        EXPECT_LE(length(ray.origin - camera.position()), kLensRadius * 1.0001f);
        EXPECT_NEAR(dot(ray.origin - camera.position(), camera.forward()), 0.0f, 1e-5f);
        // Distance from the focus point to the ray.
        const Vec3 to_focus = focus - ray.origin;
        const Vec3 off = to_focus - ray.direction * dot(to_focus, ray.direction);
        EXPECT_LT(length(off), 1e-4f * kFocus) << raster.x << " " << raster.y;
    }
}

TEST(ThinLens, ConnectInvertsGenerateRay) {
    const PerspectiveCamera camera = lens_camera(look_at());
    Rng rng(StreamKey{4, 0, 0, 0});
    for (int i = 0; i < 1000; ++i) {
        const Vec2 raster(rng.next_1d() * 64, rng.next_1d() * 48);
        const Vec2 u = rng.next_2d();
        const Ray ray = camera.generate_ray(raster, u);
        const float t = 0.5f + 8.0f * rng.next_1d();  // before and beyond the focus plane
        const auto c = camera.connect(ray.at(t), u);
        ASSERT_TRUE(c.has_value()) << raster.x << " " << raster.y;
        EXPECT_LT(length(c->lens_point - ray.origin), 1e-5f);
        EXPECT_NEAR(c->raster.x, raster.x, 2e-3);
        EXPECT_NEAR(c->raster.y, raster.y, 2e-3);
        // The density of that direction from that lens point is the pinhole's formula.
        const float cos_theta = dot(ray.direction, camera.forward());
        EXPECT_NEAR(camera.direction_pdf_w(ray.origin, ray.direction) * camera.image_plane_area() *
                        cos_theta * cos_theta * cos_theta,
                    1.0f, 1e-4f);
    }
    // Behind the lens: nothing.
    EXPECT_FALSE(
        camera.connect(camera.position() - camera.forward(), Vec2(0.5f, 0.5f)).has_value());
}

TEST(ThinLens, WithoutALensEveryEntryPointIsThePinholes) {
    const PerspectiveCamera pinhole(look_at(), 50.0f, 'x', 64, 48);
    Rng rng(StreamKey{5, 0, 0, 0}), a(StreamKey{6, 0, 0, 0}), b(StreamKey{6, 0, 0, 0});
    for (int i = 0; i < 100; ++i) {
        const Vec2 raster(rng.next_1d() * 64, rng.next_1d() * 48);
        const Ray r0 = pinhole.generate_ray(raster), r1 = pinhole.sample_ray(raster, a);
        EXPECT_EQ(r0.origin, r1.origin);
        EXPECT_EQ(r0.direction, r1.direction);
        EXPECT_EQ(pinhole.direction_pdf_w(r0.direction),
                  pinhole.direction_pdf_w(r0.origin, r0.direction));
        const Vec3 p = r0.at(3.0f);
        const auto c = pinhole.sample_connection(p, a);
        ASSERT_TRUE(c.has_value());
        EXPECT_EQ(c->lens_point, pinhole.position());
        EXPECT_EQ(c->raster.x, pinhole.raster_position(p)->x);
        EXPECT_EQ(c->raster.y, pinhole.raster_position(p)->y);
    }
    // No random number was drawn for a lens.
    EXPECT_EQ(a.next_1d(), b.next_1d());
}

CHI_SQUARE_TEST(family, ThinLens, LensPointsAreUniformOnTheDisk, 1) {
    // The identity transform: the lens is the disk of radius r in the z = 0 plane.
    const PerspectiveCamera camera = lens_camera(Transform());
    const Vec3 target(0.2f, -0.1f, 5.0f);
    ChiSquareOptions options;
    options.sample_count = 400000;
    options.seed = 11;
    const ChiSquareResult r = testing::chi_square_test_2d(
        family,
        [&](Rng& rng) -> std::optional<Vec2> {
            const auto c = camera.connect(target, rng.next_2d());
            if (!c) return std::nullopt;
            return Vec2(c->lens_point.x, c->lens_point.y);
        },
        [](Vec2 p) {
            return p.x * p.x + p.y * p.y <= kLensRadius * kLensRadius
                       ? 1.0 / (kPi * kLensRadius * kLensRadius)
                       : 0.0;
        },
        {-kLensRadius, kLensRadius, -kLensRadius, kLensRadius}, options);
    EXPECT_TRUE(r.passed) << r.message;
    EXPECT_NEAR(r.pdf_integral, 1.0, 1e-2);  // the disk's edge cells are integrated coarsely
}

// From a fixed lens point, the directions of uniformly drawn raster positions against
// direction_pdf_w(lens point, direction). Histogrammed where they cross the focus plane, in
// (x / f, y / f), the image window's own coordinates: a histogram over the sphere would cut the
// window's edges through cells (a density discontinuity the cell quadrature misses). The density
// there is direction_pdf_w times the Jacobian f^2 cos / dist^2 of solid angle per unit (x/f, y/f).
CHI_SQUARE_TEST(family, ThinLens, DirectionsFromALensPointFollowTheirDensity, 3) {
    const PerspectiveCamera camera = lens_camera(Transform());  // camera space = world space
    const float tan_x = std::tan(0.5f * 50.0f * kPi / 180.0f), tan_y = tan_x * 48.0f / 64.0f;
    for (const Vec2 u_lens : {Vec2(0.5f, 0.5f), Vec2(0.05f, 0.9f), Vec2(0.97f, 0.3f)}) {
        SCOPED_TRACE(std::to_string(u_lens.x) + " " + std::to_string(u_lens.y));
        const Vec3 lens = camera.generate_ray(Vec2(0, 0), u_lens).origin;
        ChiSquareOptions options;
        options.sample_count = 400000;
        options.seed = 12;
        const ChiSquareResult r = testing::chi_square_test_2d(
            family,
            [&](Rng& rng) -> std::optional<Vec2> {
                const Vec2 u = rng.next_2d();
                const Ray ray = camera.generate_ray(Vec2(u.x * 64, u.y * 48), u_lens);
                const Vec3 q = ray.at((kFocus - ray.origin.z) / ray.direction.z);
                return Vec2(q.x / kFocus, q.y / kFocus);
            },
            [&](Vec2 c) {
                const Vec3 w = Vec3(c.x * kFocus, c.y * kFocus, kFocus) - lens;
                const double dist2 = double(length_squared(w)), cos = kFocus / std::sqrt(dist2);
                return double(camera.direction_pdf_w(lens, w / float(std::sqrt(dist2)))) * kFocus *
                       kFocus * cos / dist2;
            },
            {-tan_x, tan_x, -tan_y, tan_y}, options);
        EXPECT_TRUE(r.passed) << r.message;
        EXPECT_NEAR(r.pdf_integral, 1.0, 1e-3);
    }
}

}  // namespace
}  // namespace render
