// PointLight: illuminate / emit / radiance report the same radiance and densities for the same
// point and direction, a chi-square test of emitted directions, and inverse-square irradiance.

#include "core/lights/point_light.h"

#include <gtest/gtest.h>

#include <optional>

#include "core/math/constants.h"
#include "tests/support/chi_square.h"
#include "tests/support/light_fixtures.h"

namespace render::testing {
namespace {

// The chi-square checks of this file, Sidak-corrected together (tests/support/chi_square.h).
ChiSquareFamily family;

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
    MeanEstimate e = irradiance(light, p, n, 1000, 1);
    EXPECT_NEAR(e.mean, 3.0 * cos / d2, 1e-6);
}

CHI_SQUARE_TEST(family, PointLight, EmitIsUniformAndAgreesWithIlluminate, 1) {
    PointLight light(Vec3(1, 2, 3), Rgb(2));
    auto sample = [&](Rng& rng) -> std::optional<Vec3> {
        LightEmitSample s;
        if (!light.emit(rng.next_2d(), rng.next_2d(), s)) return std::nullopt;
        return s.direction;
    };
    ChiSquareResult r = chi_square_test_sphere(
        family, sample, [](const Vec3&) { return double(kInv4Pi); }, ChiSquareOptions());
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

}  // namespace
}  // namespace render::testing
