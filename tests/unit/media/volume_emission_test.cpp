// Emission inside participating media (`radiance` on homogeneous and heterogeneous media,
// docs/design/media.md "Emission in media") in volpt, against closed forms:
//   - an emitting, absorbing sphere seen from outside: L = L_e (sigma_a / sigma_t)
//     (1 - exp(-sigma_t chord)) per channel;
//   - a closed furnace: a medium of any albedo < 1 emitting L_e inside black walls that emit
//     L_e too has L = L_e everywhere (sigma_a (L_e - L) = 0 in the transfer equation);
//   - the same with grid (heterogeneous) media of constant data, tracked stochastically;
//   - the scene format's validation; which algorithms refuse emitting media (pt, vpl, ic;
//     the bidirectional family an unbounded one: volume_emitter_test.cpp renders the others).
// Every statistical check states its tolerance in standard errors.

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <string>

#include "core/base/error.h"
#include "core/media/medium.h"
#include "core/render/algorithms.h"
#include "core/render/render_iterations.h"
#include "core/render/render_options.h"
#include "core/scene/loader/scene_loader.h"
#include "core/scene/pbrt/scene_loader.h"
#include "tests/support/emitting_grid_medium.h"
#include "tests/support/emitting_sphere_scene.h"
#include "tests/support/pixel_statistics.h"
#include "tests/support/test_scenes.h"

namespace render {
namespace {

using testing::pixel_statistics;
using testing::PixelStatistics;

IterationResult render_volpt(const Scene& scene, uint64_t iterations, uint64_t seed = 4321,
                             int max_depth = -1) {
    RenderSettings settings;
    settings.algorithm = "volpt";
    settings.seed = seed;
    settings.max_depth = max_depth;
    return render_iterations(scene, settings, 0, IterationRange{1, 1 + iterations});
}

// The constant grids of tests/support/emitting_grid_medium.h.
std::filesystem::path grid_folder() {
    static const std::filesystem::path dir =
        testing::constant_emission_grids("volume_emission_test");
    return dir;
}

constexpr double kSigmaT[3] = {0.5, 1.0, 4.0};
constexpr double kRadiance[3] = {1.0, 2.0, 0.5};

// The emitting medium: homogeneous (constant RGB) or heterogeneous with the grids above.
std::string medium_xml(bool grid, const std::string& albedo,
                       const std::string& sigma_t_file = "sigma_t.vol") {
    return testing::emitting_medium_xml(grid, albedo, sigma_t_file);
}

// A unit sphere of emitting, absorbing medium seen from outside (tests/support): every pixel
// sees the closed form of the chord 2 sqrt(1 - y^2).
std::string sphere_seen_from_outside(bool grid, double y = 0, const std::string& albedo = "0") {
    return testing::emitting_sphere_seen_from_outside(medium_xml(grid, albedo), y);
}

double sphere_radiance(int channel, double y = 0) {
    const double chord = 2.0 * std::sqrt(1.0 - y * y);
    return kRadiance[channel] * (1.0 - std::exp(-kSigmaT[channel] * chord));
}

TEST(VolumeEmission, HomogeneousAbsorbingSphereMatchesTheClosedForm) {
    for (const double y : {0.0, 0.8}) {  // chords 2 and 1.2
        auto scene = load_scene_from_string(sphere_seen_from_outside(false, y), ".");
        IterationResult r = render_volpt(*scene, 4);
        EXPECT_EQ(r.stats.non_finite, 0u);
        for (int channel = 0; channel < 3; ++channel) {
            // The homogeneous emission integral is in closed form: every sample is exact, and
            // only float rounding and the chord's spread (relative 1e-6) remain: relative 1e-5.
            const PixelStatistics s = pixel_statistics(r, channel);
            const double expected = sphere_radiance(channel, y);
            EXPECT_NEAR(s.mean, expected, 1e-5 * expected) << "y " << y << " channel " << channel;
        }
    }
}

TEST(VolumeEmission, GridAbsorbingSphereMatchesTheClosedForm) {
    // Tracking estimates the emission integral stochastically (spectral tracking: sigma_t
    // differs per channel): 5 standard errors.
    for (const double y : {0.0, 0.8}) {
        auto scene =
            load_scene_from_string(sphere_seen_from_outside(true, y), grid_folder().string());
        IterationResult r = render_volpt(*scene, 64);
        EXPECT_EQ(r.stats.non_finite, 0u);
        for (int channel = 0; channel < 3; ++channel) {
            const PixelStatistics s = pixel_statistics(r, channel);
            const double expected = sphere_radiance(channel, y);
            ASSERT_GT(s.standard_error, 0.0);
            EXPECT_NEAR(s.mean, expected, 5 * s.standard_error)
                << "y " << y << " channel " << channel;
            EXPECT_LT(s.standard_error, 0.02 * expected);
        }
    }
}

// With scattering (albedo 0.6) and max_depth 1 only the camera segment's own emission counts
// (paths of one segment): L = L_e (sigma_a / sigma_t) (1 - exp(-sigma_t chord)), the closed form
// of docs/design/media.md, "Emission in media", with sigma_a / sigma_t = 0.4.
TEST(VolumeEmission, ScatteringSphereAtDepthOneMatchesTheClosedForm) {
    for (const bool grid : {false, true}) {
        auto scene = load_scene_from_string(sphere_seen_from_outside(grid, 0.8, "0.6"),
                                            grid_folder().string());
        IterationResult r = render_volpt(*scene, grid ? 64 : 4, 4321, 1);
        EXPECT_EQ(r.stats.non_finite, 0u);
        for (int channel = 0; channel < 3; ++channel) {
            const PixelStatistics s = pixel_statistics(r, channel);
            const double expected = 0.4 * sphere_radiance(channel, 0.8);
            if (!grid) {  // closed form: exact up to rounding
                EXPECT_NEAR(s.mean, expected, 1e-5 * expected) << "channel " << channel;
                continue;
            }
            ASSERT_GT(s.standard_error, 0.0);
            EXPECT_NEAR(s.mean, expected, 5 * s.standard_error) << "grid channel " << channel;
            EXPECT_LT(s.standard_error, 0.02 * expected);
        }
    }
}

// The emitting medium inside a closed sphere of radius 1 whose black walls (reflectance 0)
// emit L_e, the camera inside: L = L_e in every direction, whatever the albedo (< 1) and
// sigma_t, by light found both through the medium and on the walls (NEE and phase sampling
// combined by MIS).
std::string closed_furnace(bool grid, const std::string& albedo,
                           const std::string& sigma_t_file = "sigma_t.vol") {
    return testing::medium_sphere_furnace(medium_xml(grid, albedo, sigma_t_file), "glow", "0",
                                          "1, 2, 0.5");
}

struct FurnaceCase {
    bool grid;
    const char* albedo;
    uint64_t iterations = 64;
    double max_relative_error = 0.03;          // bound on the standard error / L_e
    const char* sigma_t_file = "sigma_t.vol";  // grid: RGB (spectral tracking) or grey
};

class EmittingFurnace : public ::testing::TestWithParam<FurnaceCase> {};

TEST_P(EmittingFurnace, RadianceEqualsTheEmittedRadiance) {
    const FurnaceCase& c = GetParam();
    auto scene = load_scene_from_string(closed_furnace(c.grid, c.albedo, c.sigma_t_file),
                                        grid_folder().string());
    IterationResult r = render_volpt(*scene, c.iterations);
    EXPECT_EQ(r.stats.non_finite, 0u);
    for (int channel = 0; channel < 3; ++channel) {
        const PixelStatistics s = pixel_statistics(r, channel);
        ASSERT_GT(s.standard_error, 0.0);
        // 5 standard errors: a false failure has probability < 1e-6 per check.
        EXPECT_NEAR(s.mean, kRadiance[channel], 5 * s.standard_error)
            << (c.grid ? "grid" : "homogeneous") << " albedo " << c.albedo << " channel "
            << channel;
        EXPECT_LT(s.standard_error, c.max_relative_error * kRadiance[channel]);
    }
}

// Albedo 0.95: long paths whose spectral-MIS weights (up to 3 albedo per scattering for the
// blue channel, sigma_t 4 against 0.5 and 1) make the blue estimate heavy-tailed, as in
// volpt_test's chromatic furnace: its standard error at 512 iterations is about 3 %.
INSTANTIATE_TEST_SUITE_P(Volpt, EmittingFurnace,
                         ::testing::Values(FurnaceCase{false, "0"}, FurnaceCase{false, "0.6"},
                                           FurnaceCase{false, "0.95", 512, 0.05},
                                           FurnaceCase{true, "0"}, FurnaceCase{true, "0.6"},
                                           FurnaceCase{true, "0.6", 64, 0.03, "sigma_t_grey.vol"}));

// An infinite homogeneous medium (no surfaces) emitting L_e with albedo 0.5: the camera sees
// L_e. Each segment's emission is in closed form (sigma_a L_e / sigma_t at infinite length),
// so only the path's Russian roulette adds noise.
TEST(VolumeEmission, InfiniteMediumRadianceIsTheEmittedRadiance) {
    const std::string xml = R"(<scene version="3.0.0">
  <medium type="homogeneous" id="glow">
    <rgb name="sigma_t" value="0.5, 1, 4"/>
    <float name="albedo" value="0.5"/>
    <rgb name="radiance" value="1, 2, 0.5"/>
  </medium>
  <sensor type="perspective">
    <float name="fov" value="60"/>
    <film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="8"/></film>
    <ref id="glow"/>
  </sensor>
</scene>)";
    auto scene = load_scene_from_string(xml, ".");
    IterationResult r = render_volpt(*scene, 64);
    EXPECT_EQ(r.stats.non_finite, 0u);
    for (int channel = 0; channel < 3; ++channel) {
        const PixelStatistics s = pixel_statistics(r, channel);
        ASSERT_GT(s.standard_error, 0.0);
        EXPECT_NEAR(s.mean, kRadiance[channel], 5 * s.standard_error) << "channel " << channel;
        EXPECT_LT(s.standard_error, 0.03 * kRadiance[channel]);
    }
}

// A grid medium whose data are constant renders the homogeneous medium's image (the
// absorbing sphere and the furnace): block means agree within 5 combined standard errors.
TEST(VolumeEmission, ConstantGridMatchesHomogeneous) {
    for (const bool furnace : {false, true}) {
        const std::string hom =
            furnace ? closed_furnace(false, "0.6") : sphere_seen_from_outside(false);
        const std::string het =
            furnace ? closed_furnace(true, "0.6") : sphere_seen_from_outside(true);
        auto a = load_scene_from_string(hom, grid_folder().string());
        auto b = load_scene_from_string(het, grid_folder().string());
        IterationResult ra = render_volpt(*a, 64, 11), rb = render_volpt(*b, 64, 12);
        for (int channel = 0; channel < 3; ++channel) {
            const PixelStatistics sa = pixel_statistics(ra, channel);
            const PixelStatistics sb = pixel_statistics(rb, channel);
            const double se = std::hypot(sa.standard_error, sb.standard_error);
            ASSERT_GT(se, 0.0);
            EXPECT_NEAR(sa.mean, sb.mean, 5 * se)
                << (furnace ? "furnace" : "sphere") << " channel " << channel;
        }
    }
}

// The same sphere in a pbrt-v4 file: pbrt's medium emission `Le` (times `Lescale`; source term
// sigma_a Le, as ours) maps onto `radiance`. Homogeneous: sigma_a (0.5, 1, 4), Le (0.5, 1,
// 0.25), Lescale 2, i.e. the Mitsuba scene's L_e (1, 2, 0.5). uniformgrid: one voxel of
// density 1 (sigma_t = sigma_a) and an Lescale grid of 2 x 2 x 2 values all 2 (a grid, not a
// constant: the same radiance everywhere, read through the grid path). Both render like the
// Mitsuba scene: the homogeneous one to rounding, the grid by tracking within 5 standard
// errors.
std::string pbrt_sphere_seen_from_outside(bool grid, double y) {
    const std::string ys = std::to_string(y);
    const std::string medium =
        grid ? "\"string type\" \"uniformgrid\" \"integer nx\" 2 \"integer ny\" 2 "
               "\"integer nz\" 2 \"float density\" [1 1 1 1 1 1 1 1] \"float Lescale\" [2 2 2 2 "
               "2 2 2 2] \"point3 p0\" [-1.25 -1.25 -1.25] \"point3 p1\" [1.25 1.25 1.25] "
             : "\"string type\" \"homogeneous\" \"float Lescale\" 2 ";
    return "LookAt 0 " + ys + " -5  0 " + ys +
           " 0  0 1 0\nCamera \"perspective\" \"float fov\" 0.02\n"
           "Film \"rgb\" \"integer xresolution\" 8 \"integer yresolution\" 8\nWorldBegin\n"
           "MakeNamedMedium \"glow\" " +
           medium +
           "\"rgb sigma_a\" [0.5 1 4] \"rgb sigma_s\" [0 0 0] \"rgb Le\" [0.5 1 0.25]\n"
           "AttributeBegin\nMediumInterface \"glow\" \"\"\nMaterial \"interface\"\n"
           "Shape \"sphere\" \"float radius\" 1\nAttributeEnd\n";
}

TEST(VolumeEmission, PbrtMediumEmissionRendersLikeTheMitsubaScene) {
    for (const double y : {0.0, 0.8}) {
        auto mitsuba = load_scene_from_string(sphere_seen_from_outside(false, y), ".");
        const IterationResult reference = render_volpt(*mitsuba, 4);
        auto homogeneous = pbrt::load_scene_from_string(pbrt_sphere_seen_from_outside(false, y),
                                                        std::filesystem::path("."));
        const IterationResult h = render_volpt(*homogeneous, 4);
        auto grid = pbrt::load_scene_from_string(pbrt_sphere_seen_from_outside(true, y),
                                                 std::filesystem::path("."));
        ASSERT_TRUE(grid->media().size() == 1 && !grid->media()[0]->is_homogeneous());
        const IterationResult g = render_volpt(*grid, 64);
        EXPECT_EQ(h.stats.non_finite + g.stats.non_finite, 0u);
        for (int channel = 0; channel < 3; ++channel) {
            SCOPED_TRACE("y " + std::to_string(y) + " channel " + std::to_string(channel));
            const double expected = sphere_radiance(channel, y);
            EXPECT_NEAR(pixel_statistics(reference, channel).mean, expected, 1e-5 * expected);
            EXPECT_NEAR(pixel_statistics(h, channel).mean, expected, 1e-5 * expected);
            const PixelStatistics s = pixel_statistics(g, channel);
            ASSERT_GT(s.standard_error, 0.0);
            EXPECT_NEAR(s.mean, expected, 5 * s.standard_error);
            EXPECT_LT(s.standard_error, 0.02 * expected);
        }
    }
}

TEST(VolumeEmission, NonEmissiveMediaReportNoEmission) {
    auto scene = load_scene_from_string(R"(<scene version="3.0.0">
  <medium type="homogeneous" id="fog"><rgb name="radiance" value="0"/></medium>
  <medium type="heterogeneous" id="smoke"><rgb name="radiance" value="0"/></medium>
  <medium type="homogeneous" id="black"><float name="albedo" value="1"/><rgb name="radiance" value="3"/></medium>
  <sensor type="perspective"><ref id="fog"/></sensor>
</scene>)",
                                        ".");
    for (const auto& m : scene->media()) EXPECT_FALSE(m->is_emissive()) << m->to_string();
}

TEST(VolumeEmission, SceneFormatRefusesBadRadiance) {
    const auto load = [](const std::string& medium) {
        return load_scene_from_string(R"(<scene version="3.0.0">
  <sensor type="perspective"/>
)" + medium + R"(
</scene>)",
                                      grid_folder().string());
    };
    for (
        const std::string& medium :
        {std::string(
             R"(<medium type="homogeneous"><rgb name="radiance" value="1, -1, 1"/></medium>)"),
         std::string(R"(<medium type="homogeneous"><float name="radiance" value="inf"/></medium>)"),
         std::string(R"(<medium type="homogeneous"><float name="radiance" value="nan"/></medium>)"),
         std::string(R"(<medium type="heterogeneous"><rgb name="radiance" value="-2"/></medium>)"),
         std::string(
             R"(<medium type="heterogeneous"><volume type="constvolume" name="radiance"><float name="value" value="-1"/></volume></medium>)")}) {
        try {
            load(medium);
            ADD_FAILURE() << "accepted: " << medium;
        } catch (const SceneError& e) {
            const std::string what = e.what();
            EXPECT_NE(what.find(":3"), std::string::npos) << what;  // file:line of the medium
            // The medium's parameter, or the nested volume's value.
            EXPECT_TRUE(what.find("radiance") != std::string::npos ||
                        what.find("constvolume") != std::string::npos)
                << what;
        }
    }
    // A homogeneous medium's radiance is a constant, not a volume.
    EXPECT_THROW(
        load(R"(<medium type="homogeneous"><volume type="constvolume" name="radiance"/></medium>)"),
        SceneError);
}

// pt, vpl and ic refuse every emitting medium; the bidirectional family (upbp included) renders
// those inside closed shapes (as lights, volume_emitter_test.cpp) and refuses an unbounded one by
// name.
TEST(VolumeEmission, AlgorithmsWithoutVolumeLightsRefuseEmissiveMedia) {
    const std::string infinite = R"(<scene version="3.0.0">
  <medium type="homogeneous" id="glow"><float name="albedo" value="0.5"/><rgb name="radiance" value="1"/></medium>
  <sensor type="perspective"><ref id="glow"/></sensor>
</scene>)";
    for (const bool grid : {false, true}) {
        auto scene = load_scene_from_string(closed_furnace(grid, "0.6"), grid_folder().string());
        EXPECT_NO_THROW(check_algorithm_supports_scene("volpt", *scene));
        for (const char* algorithm : {"lt", "bpt", "ppm", "bpm", "vcm", "upbp"})
            EXPECT_NO_THROW(check_algorithm_supports_scene(algorithm, *scene)) << algorithm;
        for (const char* algorithm : {"pt", "vpl", "ic"}) {
            try {
                check_algorithm_supports_scene(algorithm, *scene);
                ADD_FAILURE() << algorithm << " accepted an emissive medium";
            } catch (const std::invalid_argument& e) {
                const std::string what = e.what();
                EXPECT_NE(what.find("medium \"glow\""), std::string::npos) << what;
                EXPECT_NE(what.find("volpt"), std::string::npos) << what;
                EXPECT_NE(what.find("emits"), std::string::npos) << what;
            }
            RenderSettings settings;
            settings.algorithm = algorithm;
            EXPECT_THROW(render_iterations(*scene, settings, 0, IterationRange{1, 2}),
                         std::invalid_argument)
                << algorithm;
        }
    }
    auto scene = load_scene_from_string(infinite, ".");
    EXPECT_NO_THROW(check_algorithm_supports_scene("volpt", *scene));
    for (const char* algorithm : {"lt", "bpt", "vcm", "upbp"}) {
        try {
            check_algorithm_supports_scene(algorithm, *scene);
            ADD_FAILURE() << algorithm << " accepted an unbounded emitting medium";
        } catch (const std::invalid_argument& e) {
            const std::string what = e.what();
            EXPECT_NE(what.find("medium \"glow\""), std::string::npos) << what;
            EXPECT_NE(what.find("unbounded"), std::string::npos) << what;
            EXPECT_NE(what.find("volpt"), std::string::npos) << what;
        }
    }
}

}  // namespace
}  // namespace render
