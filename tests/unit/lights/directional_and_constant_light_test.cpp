// The lights at infinity with a constant distribution: DirectionalLight and ConstantLight
// (uniform background). Their sampling routines against each other and Monte Carlo irradiance
// against closed forms.

#include <gtest/gtest.h>

#include <cmath>

#include "core/lights/constant_light.h"
#include "core/lights/directional_light.h"
#include "core/math/constants.h"
#include "tests/support/light_fixtures.h"

namespace render::testing {
namespace {

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

}  // namespace
}  // namespace render::testing
