// SpotLight (Mitsuba's `spot` emitter): the falloff profile and defaults, illuminate / emit
// agreeing on radiance and densities, a chi-square test of emitted directions against the
// emission density, and the emitted power against the integral of the intensity.

#include "core/lights/spot_light.h"

#include <gtest/gtest.h>

#include <cmath>
#include <optional>

#include "core/base/properties.h"
#include "core/lights/light_factory.h"
#include "core/math/constants.h"
#include "core/math/transform.h"
#include "core/render/render_iterations.h"
#include "core/render/render_options.h"
#include "core/sampling/rng.h"
#include "core/scene/loader/scene_loader.h"
#include "core/textures/texture_factory.h"
#include "tests/support/chi_square.h"
#include "tests/support/light_fixtures.h"
#include "tests/support/statistics.h"

namespace render::testing {
namespace {

ChiSquareFamily family;

constexpr float kDegree = kPi / 180.0f;

// A unit direction at angle theta (radians) from the frame's axis, at azimuth phi.
Vec3 at_angle(const Frame& frame, float theta, float phi = 0.4f) {
    return frame.to_world(
        Vec3(std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi), std::cos(theta)));
}

// A spot at (1, 2, 3) pointing at `target` (the origin by default), built by the factory from
// Mitsuba parameters.
std::unique_ptr<Light> factory_spot(std::optional<float> cutoff, std::optional<float> beam,
                                    const Rgb& intensity, const Vec3& target = Vec3(0.0f)) {
    Properties props("emitter", "spot", SourceLocation{"scene.xml", 3});
    const SourceLocation at{"scene.xml", 4};
    props.set("intensity", intensity, at);
    if (cutoff) props.set("cutoff_angle", *cutoff, at);
    if (beam) props.set("beam_width", *beam, at);
    props.set("to_world", Transform::look_at(Vec3(1, 2, 3), target, Vec3(0, 1, 0)), at);
    std::unique_ptr<Light> light = make_light(props, nullptr, ".");
    props.check_all_used();
    return light;
}

Frame axis_frame() {
    return Frame::from_normal(normalize(Vec3(-1, -2, -3)));
}

TEST(SpotLight, FactoryDefaultsAndMitsubaFalloff) {
    // Defaults: cutoff 20 degrees, beam width 3/4 of it (15 degrees); linear in the angle.
    auto light = factory_spot(std::nullopt, std::nullopt, Rgb(2, 3, 4));
    const auto& spot = dynamic_cast<const SpotLight&>(*light);
    const Frame frame = axis_frame();
    EXPECT_NEAR(spot.falloff(frame.n), 1.0f, 1e-6f);
    EXPECT_NEAR(spot.falloff(at_angle(frame, 14.9f * kDegree)), 1.0f, 1e-6f);
    EXPECT_NEAR(spot.falloff(at_angle(frame, 17.5f * kDegree)), 0.5f, 1e-3f);
    EXPECT_NEAR(spot.falloff(at_angle(frame, 19.0f * kDegree)), 0.2f, 1e-3f);
    EXPECT_EQ(spot.falloff(at_angle(frame, 20.1f * kDegree)), 0.0f);
    EXPECT_EQ(spot.falloff(-frame.n), 0.0f);
    EXPECT_EQ(spot.position(), Vec3(1, 2, 3));
    EXPECT_TRUE(light->is_delta());
    EXPECT_TRUE(light->is_finite());
    EXPECT_TRUE(light->radiance(Vec3(1, 2, 3), Vec3(0, 0, 1), -frame.n).radiance.is_black());

    // A beam as wide as the cutoff: a hard-edged cone.
    auto hard = factory_spot(30.0f, 30.0f, Rgb(1));
    EXPECT_EQ(dynamic_cast<const SpotLight&>(*hard).falloff(at_angle(frame, 29.9f * kDegree)),
              1.0f);
    expect_close(hard->power(), Rgb(2 * kPi * (1 - std::cos(30 * kDegree))));
}

TEST(SpotLight, IlluminateFollowsPointLightConvention) {
    auto light = factory_spot(40.0f, 10.0f, Rgb(4, 5, 6));
    const auto& spot = dynamic_cast<const SpotLight&>(*light);
    light->preprocess(test_scene_sphere());
    const Frame frame = axis_frame();
    const float cone_pdf = 1.0f / (2 * kPi * (1 - std::cos(40 * kDegree)));
    for (float degrees : {0.0f, 5.0f, 25.0f, 39.0f}) {
        SCOPED_TRACE(degrees);
        const Vec3 w = at_angle(frame, degrees * kDegree);
        const Vec3 ref = spot.position() + w * 2.5f;
        LightIlluminateSample s;
        ASSERT_TRUE(light->illuminate(ref, Vec2(0.3f, 0.7f), s));
        EXPECT_NEAR(dot(s.wi, w), -1.0f, 1e-5f);
        EXPECT_NEAR(s.distance, 2.5f, 1e-5f);
        const float f = degrees <= 10 ? 1.0f : (40 - degrees) / 30.0f;
        expect_close(s.radiance, Rgb(4, 5, 6) * f, 1e-3f);
        expect_close(s.pdf_direct_w, 6.25f);
        expect_close(s.pdf_emission_w, cone_pdf);
        EXPECT_EQ(s.cos_at_light, 1.0f);
    }
    // Outside the cone (and behind the light) nothing arrives.
    LightIlluminateSample s;
    EXPECT_FALSE(light->illuminate(spot.position() + at_angle(frame, 41 * kDegree), Vec2(), s));
    EXPECT_FALSE(light->illuminate(spot.position() - frame.n, Vec2(), s));
    EXPECT_FALSE(light->illuminate(spot.position(), Vec2(), s));
}

CHI_SQUARE_TEST(family, SpotLight, EmitFollowsConeDensityAndAgreesWithIlluminate, 1) {
    // Pointing along +z, the histogram's axis, with cos(cutoff) = 0.75 on a cell boundary:
    // the density's jump at the cone's edge then falls between cells.
    const float cutoff = std::acos(0.75f) / kDegree;
    auto light = factory_spot(cutoff, 20.0f, Rgb(2), Vec3(1, 2, 4));
    const auto& spot = dynamic_cast<const SpotLight&>(*light);
    auto sample = [&](Rng& rng) -> std::optional<Vec3> {
        LightEmitSample s;
        const Vec2 u_position = rng.next_2d();
        if (!light->emit(u_position, rng.next_2d(), s)) return std::nullopt;
        return s.direction;
    };
    ChiSquareOptions options;
    options.resolution_x = 64;
    options.resolution_y = 128;  // cells of 1/64 in cos theta: a boundary at 0.75
    ChiSquareResult r = chi_square_test_sphere(
        family, sample, [&](const Vec3& w) { return double(spot.emission_pdf_w(w)); }, options);
    EXPECT_TRUE(r.passed) << r.message;
    EXPECT_NEAR(r.pdf_integral, 1.0, 2e-3);

    Rng rng(StreamKey{5, 0, 1, 0});
    for (int i = 0; i < 1000; ++i) {
        LightEmitSample e;
        if (!light->emit(rng.next_2d(), rng.next_2d(), e)) continue;
        EXPECT_EQ(e.origin, spot.position());
        EXPECT_NEAR(length(e.direction), 1.0f, 1e-5f);
        // Absolute tolerances: near the cone's edge the falloff is a small difference of
        // angles.
        EXPECT_NEAR(e.energy.r, 2 * spot.falloff(e.direction), 2e-5f);
        EXPECT_EQ(e.pdf_direct_a, 1.0f);
        expect_close(e.pdf_emission_w, spot.emission_pdf_w(e.direction));
        // Illuminating a point on the emitted ray reports the same emission density and the
        // same radiance (energy, as cos_at_light is 1).
        LightIlluminateSample s;
        ASSERT_TRUE(light->illuminate(e.origin + e.direction * 1.5f, Vec2(0.5f, 0.5f), s));
        expect_close(s.pdf_emission_w, e.pdf_emission_w);
        EXPECT_NEAR(s.radiance.g, e.energy.g, 1e-4f);
    }
}

TEST(SpotLight, EmittedPowerIntegratesTheIntensity) {
    for (auto [cutoff, beam] : {std::pair{20.0f, 15.0f}, std::pair{60.0f, 0.0f},
                                std::pair{120.0f, 90.0f}, std::pair{45.0f, 45.0f}}) {
        SCOPED_TRACE(cutoff);
        auto light = factory_spot(cutoff, beam, Rgb(1.0f, 2.0f, 0.5f));
        const Rgb power = light->power();
        // 1. The closed form against a quadrature of the profile over theta.
        const double c = cutoff * kDegree, b = beam * kDegree;
        const double quadrature =
            2 * M_PI *
            integrate_graded(
                [&](double t) {
                    const double f = t <= b ? 1.0 : t >= c ? 0.0 : (c - t) / (c - b);
                    return f * std::sin(t);
                },
                0.0, M_PI, c, 1e-3);
        EXPECT_NEAR(power.r, quadrature, 1e-4 * quadrature);
        // 2. The flux through a sphere around the light, from illuminate(): the irradiance
        // radiance / pdf_direct_w at normal incidence times the area r^2 dOmega, summed over
        // a midpoint grid in (cos theta, phi) about the light's axis.
        const Frame frame = axis_frame();
        const Vec3 p = dynamic_cast<const SpotLight&>(*light).position();
        const int n_theta = 4000, n_phi = 16;
        const float radius = 3.0f;
        double flux = 0;
        for (int i = 0; i < n_theta; ++i)
            for (int j = 0; j < n_phi; ++j) {
                const double z = 1 - 2 * (i + 0.5) / n_theta, phi = 2 * M_PI * (j + 0.5) / n_phi;
                const double s = std::sqrt(std::max(0.0, 1 - z * z));
                const Vec3 w = frame.to_world(
                    Vec3(float(s * std::cos(phi)), float(s * std::sin(phi)), float(z)));
                LightIlluminateSample sample;
                if (!light->illuminate(p + w * radius, Vec2(0.5f, 0.5f), sample)) continue;
                flux += sample.radiance.g / sample.pdf_direct_w * radius * radius;
            }
        flux *= 4 * M_PI / (n_theta * n_phi);
        EXPECT_NEAR(flux, power.g, 2e-3 * power.g);
        // 3. Light paths carry the same power: E[energy / pdf_emission_w] over emit().
        MeanAccumulator mean;
        Rng rng(StreamKey{11, 0, 1, 0});
        for (int i = 0; i < 200000; ++i) {
            LightEmitSample e;
            mean.add(light->emit(rng.next_2d(), rng.next_2d(), e) ? e.energy.b / e.pdf_emission_w
                                                                  : 0.0);
        }
        EXPECT_NEAR(mean.mean(), power.b, 4 * mean.standard_error() + 1e-5 * power.b);
    }
}

// Mitsuba 3's projected `texture`: a checkerboard (color0 where the fractional parts of 3 u and
// 2 v are on the same side of 1/2) over the cone's square of half-angle cutoff. The intensity
// toward the local direction (x, y, z) is I falloff texture(1/2 + x / (2 z tan cutoff), 1/2 + y /
// (2 z tan cutoff)), from illuminate() and emit() alike; the densities are the untextured ones;
// power() uses the mean.
TEST(SpotLight, ProjectedTextureScalesTheIntensity) {
    const Rgb color0(1.0f, 2.0f, 3.0f), color1(0.25f, 0.5f, 0.125f), intensity(2.0f, 3.0f, 4.0f);
    auto make = [&](bool textured) {
        Properties props("emitter", "spot", SourceLocation{"scene.xml", 3});
        const SourceLocation at{"scene.xml", 4};
        props.set("intensity", intensity, at);
        props.set("cutoff_angle", 30.0f, at);
        props.set("beam_width", 10.0f, at);
        props.set("to_world", Transform::look_at(Vec3(1, 2, 3), Vec3(0.0f), Vec3(0, 1, 0)), at);
        if (textured) {
            Properties checker("texture", "checkerboard", at);
            checker.set("color0", color0, at);
            checker.set("color1", color1, at);
            checker.set("to_uv", Transform::scale(Vec3(3, 2, 1)), at);
            props.set("texture", make_texture(checker), at);
        }
        std::unique_ptr<Light> light = make_light(props, nullptr, ".");
        props.check_all_used();
        return light;
    };
    auto textured = make(true), plain = make(false);
    const auto& spot = dynamic_cast<const SpotLight&>(*textured);
    // The light's local axes: to_world's x, y and z (the axis), as Mitsuba's.
    const Transform to_world = Transform::look_at(Vec3(1, 2, 3), Vec3(0.0f), Vec3(0, 1, 0));
    const Vec3 x = normalize(to_world.apply_vector(Vec3(1, 0, 0)));
    const Vec3 y = normalize(to_world.apply_vector(Vec3(0, 1, 0)));
    const Vec3 z = normalize(to_world.apply_vector(Vec3(0, 0, 1)));
    const float inv_tan = 1.0f / std::tan(30 * kDegree);
    auto expected = [&](const Vec3& local) {
        const float u = 0.5f + 0.5f * local.x / local.z * inv_tan;
        const float v = 0.5f + 0.5f * local.y / local.z * inv_tan;
        // The checkerboard's to_uv scales u by 3 and v by 2.
        const float fu = 3 * u - std::floor(3 * u), fv = 2 * v - std::floor(2 * v);
        const Rgb tex = (fu > 0.5f) == (fv > 0.5f) ? color0 : color1;
        return intensity * tex * spot.falloff(x * local.x + y * local.y + z * local.z);
    };
    int seen[2] = {0, 0};
    for (int i = 0; i < 400; ++i) {
        // Local directions over the cone's square (tan up to 0.6 > tan 30 = 0.577).
        const Vec3 local = normalize(Vec3(-0.6f + 1.2f * ((i * 37) % 400) / 400.0f + 0.001f,
                                          -0.6f + 1.2f * float(i) / 400.0f + 0.001f, 1.0f));
        const Vec3 dir = x * local.x + y * local.y + z * local.z;
        const Rgb want = expected(local);
        LightIlluminateSample s;
        const bool lit = textured->illuminate(Vec3(1, 2, 3) + dir * 2.0f, Vec2(0.5f, 0.5f), s);
        EXPECT_EQ(lit, !want.is_black()) << i;
        if (!lit) continue;
        for (int c = 0; c < 3; ++c) EXPECT_NEAR(s.radiance[c], want[c], 1e-4f * want[c]) << i;
        ++seen[want.r == intensity.r * color0.r * spot.falloff(dir) ? 0 : 1];
        LightIlluminateSample p;
        ASSERT_TRUE(plain->illuminate(Vec3(1, 2, 3) + dir * 2.0f, Vec2(0.5f, 0.5f), p));
        EXPECT_EQ(s.pdf_emission_w, p.pdf_emission_w);
        EXPECT_EQ(s.pdf_direct_w, p.pdf_direct_w);
    }
    EXPECT_GT(seen[0], 50);
    EXPECT_GT(seen[1], 50);
    Rng rng(StreamKey{9, 0, 1, 0});
    for (int i = 0; i < 1000; ++i) {
        const Vec2 u_position = rng.next_2d(), u_direction = rng.next_2d();
        LightEmitSample e, p;
        const bool emitted = textured->emit(u_position, u_direction, e);
        ASSERT_EQ(emitted, plain->emit(u_position, u_direction, p));
        if (!emitted) continue;
        EXPECT_EQ(e.direction, p.direction);
        EXPECT_EQ(e.pdf_emission_w, p.pdf_emission_w);
        const Vec3 local(dot(e.direction, x), dot(e.direction, y), dot(e.direction, z));
        const Rgb want = expected(local);
        // Absolute 1e-4 too: near the cone's edge the falloff is a small difference of angles.
        for (int c = 0; c < 3; ++c) EXPECT_NEAR(e.energy[c], want[c], 1e-4f * want[c] + 1e-4f);
    }
    expect_close(textured->power(), plain->power() * ((color0 + color1) * 0.5f));
}

TEST(SpotLight, ProjectedTextureRefusals) {
    auto error = [](float cutoff, Rgb color) {
        Properties props("emitter", "spot", SourceLocation{"scene.xml", 7});
        props.set("cutoff_angle", cutoff, SourceLocation{"scene.xml", 8});
        Properties checker("texture", "checkerboard", SourceLocation{"scene.xml", 9});
        checker.set("color0", color, SourceLocation{"scene.xml", 9});
        props.set("texture", make_texture(checker), SourceLocation{"scene.xml", 9});
        try {
            make_light(props, nullptr, ".");
        } catch (const SceneError& e) {
            return std::string(e.what());
        }
        return std::string("(no error)");
    };
    EXPECT_NE(error(90.0f, Rgb(1))
                  .find("scene.xml:9: emitter \"spot\", parameter \"texture\": a "
                        "projected texture needs cutoff_angle below 90"),
              std::string::npos)
        << error(90.0f, Rgb(1));
    EXPECT_NE(error(30.0f, Rgb(-1)).find("scene.xml:9:"), std::string::npos);
    EXPECT_EQ(error(89.0f, Rgb(1)), "(no error)");
}

// A Mitsuba 3 file with a projected bitmap loads and renders: the floor is lit only where the
// texture's cone reaches, and the image is finite.
TEST(SpotLight, ProjectedTextureSceneRenders) {
    auto scene = load_scene_from_string(R"(<scene version="3.0.0">
  <sensor type="perspective"><float name="fov" value="50"/>
    <transform name="to_world"><lookat origin="0, 4, 4" target="0, 0, 0" up="0, 1, 0"/></transform>
    <film type="hdrfilm"><integer name="width" value="32"/><integer name="height" value="32"/></film>
  </sensor>
  <shape type="rectangle"><transform name="to_world"><scale value="4"/><rotate x="1" angle="-90"/></transform>
    <bsdf type="diffuse"/></shape>
  <emitter type="spot">
    <transform name="to_world"><lookat origin="0, 3, 0" target="0, 0, 0" up="0, 0, 1"/></transform>
    <rgb name="intensity" value="20"/>
    <float name="cutoff_angle" value="25"/>
    <texture type="bitmap" name="texture"><string name="filename" value="textures/tiles.png"/></texture>
  </emitter>
</scene>)",
                                        std::string(RENDER_SOURCE_DIR) + "/scenes/tests");
    ASSERT_NE(scene->lights()[0]->to_string().find("texture"), std::string::npos);
    for (const std::string algorithm : {"pt", "lt", "vcm"}) {
        RenderSettings settings = resolve_render_settings(algorithm, {}, scene->settings);
        const IterationResult r = render_iterations(*scene, settings, 0, IterationRange{1, 3});
        double total = 0;
        bool finite = true;
        for (float v : r.sum.values()) total += v, finite = finite && std::isfinite(v);
        EXPECT_TRUE(finite) << algorithm;
        EXPECT_GT(total, 0.0) << algorithm;
    }
}

TEST(SpotLight, FactoryRejectsBadValuesNamingTheField) {
    auto error = [](const std::string& name, Properties::Value value) {
        Properties props("emitter", "spot", SourceLocation{"scene.xml", 7});
        props.set(name, value, SourceLocation{"scene.xml", 8});
        try {
            make_light(props, nullptr, ".");
        } catch (const SceneError& e) {
            return std::string(e.what());
        }
        return std::string("(no error)");
    };
    EXPECT_NE(error("cutoff_angle", 0.0f)
                  .find("scene.xml:8: emitter \"spot\", parameter "
                        "\"cutoff_angle\""),
              std::string::npos);
    EXPECT_NE(error("beam_width", 25.0f).find("parameter \"beam_width\""), std::string::npos);
    EXPECT_NE(error("intensity", Rgb(-1)).find("parameter \"intensity\""), std::string::npos);
    EXPECT_NE(error("to_world", Transform::scale(Vec3(1, 2, 1))).find("parameter \"to_world\""),
              std::string::npos);
}

}  // namespace
}  // namespace render::testing
