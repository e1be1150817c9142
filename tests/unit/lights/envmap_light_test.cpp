// EnvmapLight: the lat-long mapping, nearest-texel lookup, sampling routines against each
// other, a chi-square test of sampled directions in the map's own chart, Monte Carlo
// irradiance and extreme texels.

#include "core/lights/envmap_light.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <vector>

#include "core/math/constants.h"
#include "tests/support/chi_square.h"
#include "tests/support/light_fixtures.h"

namespace render::testing {
namespace {

// The chi-square checks of this file, Sidak-corrected together (tests/support/chi_square.h).
ChiSquareFamily family;

// ---------------------------------------------------------------------------------------
// Environment map

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

CHI_SQUARE_TEST(family, EnvmapLight, SampledDirectionsChiSquare, 1) {
    // Histogram in the map's own chart (u, v) on cells aligned with the texels (4 x 4 cells
    // per texel). The claimed solid-angle density becomes pdf_w * |d omega / d(u, v)| =
    // pdf_w * 2 pi^2 sin theta there; each cell's probability integrates it with a 4 x 4
    // midpoint rule (no node on a texel edge, where the density jumps), and
    // chi_square_test_discrete compares the counts with them. A rotated frame checks that
    // sampling and lookup use the same transform; the bright texel holds most of the mass.
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
    ChiSquareResult r = chi_square_test_discrete(family, observed, probability, samples);
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

}  // namespace
}  // namespace render::testing
