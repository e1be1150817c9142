#include "core/integrators/merge_radius.h"

#include <gtest/gtest.h>

#include <cmath>

#include "core/camera/perspective_camera.h"
#include "core/lights/light.h"
#include "core/math/transform.h"

namespace render {
namespace {

TEST(MergeRadius, MatchesItsFormula) {
    for (double alpha : {0.5, 0.75, 1.0})
        for (uint64_t i : {1ull, 2ull, 7ull, 1000ull, 123456789ull})
            EXPECT_NEAR(merge_radius(0.25, alpha, i), 0.25 * std::pow(double(i), (alpha - 1) / 2),
                        1e-15);
    EXPECT_EQ(merge_radius(0.3, 0.75, 1), 0.3);
}

TEST(MergeRadius, IsMonotoneAndFloored) {
    double previous = merge_radius(1.0, 0.75, 1);
    for (uint64_t i = 2; i < 100000; i += 97) {
        double r = merge_radius(1.0, 0.75, i);
        EXPECT_LE(r, previous);
        previous = r;
    }
    // alpha = 1 keeps the radius; a huge iteration index hits the floor, never zero.
    EXPECT_EQ(merge_radius(2.0, 1.0, 1000000), 2.0);
    // A scene of size 1e-12 after 2^64 iterations would reach 1e-21: the floor holds.
    double floor = merge_radius(1e-12, 0.01, ~0ull);
    EXPECT_EQ(floor, min_merge_radius());
    EXPECT_GT(floor, 0.0);
    EXPECT_TRUE(std::isfinite(float(1.0 / (M_PI * floor * floor))));
}

// A camera at the origin looking down +z with a 90 degree horizontal field of view: the image
// plane at distance 1 is 2 wide, so at W x W pixels a pixel's side there is 2 / W.
PerspectiveCamera square_camera(int pixels) {
    return PerspectiveCamera(Transform::look_at(Vec3(0, 0, 0), Vec3(0, 0, 1), Vec3(0, 1, 0)), 90,
                             'x', pixels, pixels);
}

TEST(MergeRadius, PixelFootprintIsThePixelSideAtTheSceneCentre) {
    const SceneSphere sphere{Vec3(0, 0, 10), 2};
    EXPECT_NEAR(pixel_footprint(square_camera(100), sphere), 10 * 2.0 / 100, 1e-5);
    // Four times the pixels across: a quarter of the footprint, so the default radius holds the
    // same share of a pixel at every resolution.
    EXPECT_NEAR(pixel_footprint(square_camera(400), sphere), 10 * 2.0 / 400, 1e-6);
    // Scaling the scene (and the camera's distance) scales the footprint.
    const SceneSphere scaled{Vec3(0, 0, 1000), 200};
    EXPECT_NEAR(pixel_footprint(square_camera(100), scaled), 1000 * 2.0 / 100, 1e-3);
    // A camera inside the sphere: its first hits lie about a radius away.
    const SceneSphere around{Vec3(0, 0, 1), 5};
    EXPECT_NEAR(pixel_footprint(square_camera(100), around), 5 * 2.0 / 100, 1e-6);
}

TEST(MergeRadius, InitialRadiusFollowsTheFactorOrThePixels) {
    const SceneSphere sphere{Vec3(0, 0, 10), 2};
    const PerspectiveCamera camera = square_camera(100);
    // radius_factor > 0: the scene-relative rule, whatever radius_pixels says.
    EXPECT_DOUBLE_EQ(initial_merge_radius(0.003, 7, camera, sphere), 0.003 * 2);
    // radius_factor 0: radius_pixels pixel footprints.
    EXPECT_NEAR(initial_merge_radius(0, 1.5, camera, sphere), 1.5 * 0.2, 1e-6);
}

}  // namespace
}  // namespace render
