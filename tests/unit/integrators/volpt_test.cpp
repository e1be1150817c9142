// Volumetric path tracing against closed-form answers: the furnace filled with a conserving
// medium, single scattering from a point light in an infinite medium (a 1-D integral computed
// here to high precision), and the hard cases (dense, thin, grazing, unbounded depth;
// docs/design/media.md, "Tests"). Every statistical check states its tolerance in standard errors.

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <ostream>
#include <string>
#include <vector>

#include "core/math/constants.h"
#include "core/render/render_iterations.h"
#include "core/render/render_options.h"
#include "core/scene/loader/scene_loader.h"
#include "tests/support/algorithms.h"
#include "tests/support/pixel_statistics.h"
#include "tests/support/statistics.h"
#include "tests/support/test_scenes.h"

namespace render {
namespace {

using testing::pixel_statistics;
using testing::PixelStatistics;

RenderSettings settings_for(const std::string& algorithm, bool equiangular, int max_depth,
                            double radius_factor, bool jis, void (*adjust)(RenderSettings&)) {
    RenderSettings settings;
    settings.algorithm = algorithm;
    settings.seed = 1234;
    settings.max_depth = max_depth;
    settings.equiangular = equiangular;
    settings.jis = jis;                // volpt
    settings.joint_connections = jis;  // bpt
    if (radius_factor > 0) settings.radius_factor = radius_factor;
    testing::beams_from_every_path(settings);  // upbp: every path's beams and photons
    if (adjust) adjust(settings);
    return settings;
}

IterationResult render(const std::string& xml, const std::string& algorithm, uint64_t iterations,
                       bool equiangular = true, int max_depth = -1, double radius_factor = 0,
                       bool jis = true, void (*adjust)(RenderSettings&) = nullptr) {
    auto scene = load_scene_from_string(xml, ".");
    return render_iterations(
        *scene, settings_for(algorithm, equiangular, max_depth, radius_factor, jis, adjust), 0,
        IterationRange{1, 1 + iterations});
}

// The furnace of render_test.cpp (diffuse albedo 0.5 and emission 0.5 inside a closed sphere,
// so L = 1 everywhere) filled with a medium of albedo 1: scattering moves light around
// without removing any, so L stays 1.
std::string medium_furnace(const std::string& sigma_t, const std::string& phase) {
    return testing::medium_sphere_furnace(R"(<medium type="homogeneous" id="fog">
    <rgb name="sigma_t" value=")" + sigma_t + R"("/>
    <float name="albedo" value="1"/>
    )" + phase + R"(
  </medium>)",
                                          "fog", "0.5", "0.5");
}

struct FurnaceCase {
    const char* algorithm;
    const char* sigma_t;
    const char* phase;
    bool equiangular;
    // Merging radius / scene radius (0: the default 0.003). Photon points in a 16x16 image
    // (256 light paths) need a larger ball than surface photons to find any neighbours.
    double radius_factor = 0;
    uint64_t iterations = 64;
    bool jis = true;  // joint sampling (volpt: J3; bpt, vcm: J1 connections)
    void (*adjust)(RenderSettings&) = nullptr;  // other settings (upbp's estimators)
};

// How test output and ctest name a case (gtest would print its raw bytes, pointers included,
// which change from build to build).
void PrintTo(const FurnaceCase& c, std::ostream* os) {
    const std::string phase(c.phase);
    const size_t g = phase.find("value=\"");
    *os << c.algorithm << " sigma_t=" << c.sigma_t << " "
        << (g == std::string::npos ? "isotropic"
                                   : "g=" + phase.substr(g + 7, phase.find('"', g + 7) - g - 7))
        << (c.equiangular ? "" : " no-equiangular") << " radius=" << c.radius_factor
        << " iterations=" << c.iterations << (c.jis ? "" : " no-jis")
        << (c.adjust ? " adjusted" : "");
}

class MediumFurnace : public ::testing::TestWithParam<FurnaceCase> {};

// The image mean's standard error comes from batches of iterations, not from the spread of the
// pixels: in the merging algorithms (ppm, bpm, vcm, upbp) every pixel gathers the same
// iteration's light subpaths, so the pixels' errors are correlated and their spread
// understates the error of the mean (photon beams alone in sigma_t 4: by about 6x, which once
// read a 1.4-standard-error fluctuation as 8; docs/design/media.md, "Photon beams").
constexpr uint64_t kFurnaceBatches = 16;

TEST_P(MediumFurnace, RadianceStaysOne) {
    const FurnaceCase& c = GetParam();
    ASSERT_EQ(c.iterations % kFurnaceBatches, 0u);
    auto scene = load_scene_from_string(medium_furnace(c.sigma_t, c.phase), ".");
    const RenderSettings settings =
        settings_for(c.algorithm, c.equiangular, -1, c.radius_factor, c.jis, c.adjust);
    const uint64_t per_batch = c.iterations / kFurnaceBatches;
    std::vector<double> batch_means[3];
    for (uint64_t b = 0; b < kFurnaceBatches; ++b) {
        const IterationResult r = render_iterations(
            *scene, settings, 0, IterationRange{1 + b * per_batch, 1 + (b + 1) * per_batch});
        EXPECT_EQ(r.stats.non_finite, 0u);
        for (int channel = 0; channel < 3; ++channel)
            batch_means[channel].push_back(pixel_statistics(r, channel).mean);
    }
    for (int channel = 0; channel < 3; ++channel) {
        const testing::MeanEstimate s = testing::batch_means(batch_means[channel]);
        std::printf("%s sigma_t %s channel %d: %.4f +- %.4f\n", c.algorithm, c.sigma_t, channel,
                    s.mean, s.standard_error);
        ASSERT_GT(s.standard_error, 0.0);
        // 5 standard errors: a false failure has probability < 1e-3 per check even with the
        // Student t of 15 degrees of freedom.
        EXPECT_NEAR(s.mean, 1.0, 5 * s.standard_error)
            << c.algorithm << " " << c.sigma_t << " " << c.phase << " channel " << channel;
        EXPECT_LT(s.standard_error, 0.05);
    }
}

constexpr const char* kIsotropic = R"(<phase type="isotropic"/>)";
constexpr const char* kForward = R"(<phase type="hg"><float name="g" value="0.7"/></phase>)";
constexpr const char* kBackward = R"(<phase type="hg"><float name="g" value="-0.5"/></phase>)";
constexpr const char* kPeakedForward = R"(<phase type="hg"><float name="g" value="0.99"/></phase>)";
constexpr const char* kPeakedBackward =
    R"(<phase type="hg"><float name="g" value="-0.99"/></phase>)";

// volpt runs joint sampling (jis) on the camera ray here (camera inside the medium, area
// light): the furnace checks it with every phase function, including g = +-0.99 where its
// isotropic densities are far from the phase function's lobe.
INSTANTIATE_TEST_SUITE_P(
    Volpt, MediumFurnace,
    ::testing::Values(FurnaceCase{"volpt", "1", kIsotropic, true},
                      FurnaceCase{"volpt", "1", kIsotropic, false},
                      FurnaceCase{"volpt", "1", kIsotropic, true, 0, 64, false},
                      // The blue channel (sigma_t 3) is heavy-tailed with or without jis: its
                      // standard error over seeds ranges 0.03-0.11 at 64 iterations.
                      FurnaceCase{"volpt", "0.3, 1, 3", kForward, true, 0, 512},
                      FurnaceCase{"volpt", "4", kBackward, true},
                      FurnaceCase{"volpt", "1", kPeakedForward, true},
                      FurnaceCase{"volpt", "1", kPeakedBackward, true}));

// The bidirectional family through the same media: light subpaths start in the emitter's
// medium, vertices in the medium are connected and (ppm, bpm, vcm) merged as photon points.
// bpt and vcm run their joint (J1) connections (--joint-connections on), also with g = +-0.99
// where the equi-angular densities ignore the phase function's lobe; vcm also without them.
// ppm (merging only, no MIS) runs 1024 iterations: at 256 its batch standard error was 0.057.
// lt is heavy-tailed here (probably its camera connections from medium vertices near the
// camera, 1/d^2): it reads 0.911 +- 0.037 at 64 iterations, 0.964 +- 0.014 at 1024, 0.997 +- 0.012
// at 4096.
INSTANTIATE_TEST_SUITE_P(Bidirectional, MediumFurnace,
                         ::testing::Values(FurnaceCase{"lt", "1", kIsotropic, true},
                                           FurnaceCase{"bpt", "1", kIsotropic, true},
                                           FurnaceCase{"bpt", "0.3, 1, 3", kForward, true},
                                           FurnaceCase{"bpt", "1", kPeakedForward, true},
                                           FurnaceCase{"bpt", "1", kPeakedBackward, true},
                                           FurnaceCase{"ppm", "1", kIsotropic, true, 0.02, 1024},
                                           FurnaceCase{"bpm", "1", kIsotropic, true, 0.02, 256},
                                           FurnaceCase{"vcm", "1", kIsotropic, true},
                                           FurnaceCase{"vcm", "0.3, 1, 3", kForward, true},
                                           FurnaceCase{"vcm", "4", kBackward, true},
                                           FurnaceCase{"vcm", "1", kPeakedForward, true},
                                           FurnaceCase{"vcm", "1", kPeakedBackward, true},
                                           FurnaceCase{"vcm", "1", kIsotropic, true, 0, 64, false},
                                           FurnaceCase{"vcm", "0.3, 1, 3", kForward, true, 0, 64,
                                                       false}));

// bpt with J2 (--joint-connections all: the light vertices resampled on their light rays in the
// medium, beside J1): the area light's emission rays start in the medium, so J2 runs; isotropic,
// the chromatic forward case, and g = +-0.99, where B2's and J1's isotropic densities ignore the
// phase function (the phase function is in the estimate, the densities are exact).
void with_joint2(RenderSettings& s) {
    s.joint2_connections = true;
}
INSTANTIATE_TEST_SUITE_P(
    JointSegment, MediumFurnace,
    ::testing::Values(FurnaceCase{"bpt", "1", kIsotropic, true, 0, 64, true, with_joint2},
                      // J2's distances ignore the blue channel's sigma_t 3 (JIS samples no
                      // transmittance): heavy-tailed there, SE 0.059 at 64 iterations.
                      FurnaceCase{"bpt", "0.3, 1, 3", kForward, true, 0, 512, true, with_joint2},
                      FurnaceCase{"bpt", "1", kPeakedForward, true, 0, 64, true, with_joint2},
                      FurnaceCase{"bpt", "1", kPeakedBackward, true, 0, 64, true, with_joint2}));

// upbp's query beams (P-B2D): with every estimator, and as the only one in the medium (no
// connections, no photon points: every path with a medium vertex is gathered along a camera
// segment, so an error in the beam estimate itself cannot hide behind other techniques).
// Radiance is the same everywhere in the furnace, so the kernel's only bias is at the wall,
// where the disc around a query reaches past the medium: at r = 0.02 it stays well inside
// the tolerance (measured: 0.2 % on the mean).
void query_beams_only(RenderSettings& s) {
    s.vertex_connections = false;
    s.photon_points = false;
    s.photon_beams = false;
}
// Query beams gathering the photon points of a quarter of the light paths (--query-beam-paths
// 0.25: 64 of the furnace's 256): the estimate normalised by those 64, not by all 256 (which
// would read 0.25).
void query_beams_only_from_a_quarter_of_the_paths(RenderSettings& s) {
    query_beams_only(s);
    s.query_beam_paths = 0.25;
}
INSTANTIATE_TEST_SUITE_P(
    QueryBeams, MediumFurnace,
    ::testing::Values(FurnaceCase{"upbp", "1", kIsotropic, true},
                      FurnaceCase{"upbp", "1", kIsotropic, true, 0.02, 512, true,
                                  query_beams_only_from_a_quarter_of_the_paths},
                      FurnaceCase{"upbp", "0.3, 1, 3", kForward, true},
                      FurnaceCase{"upbp", "1", kIsotropic, true, 0.02, 256, true, query_beams_only},
                      FurnaceCase{"upbp", "4", kBackward, true, 0.02, 256, true,
                                  query_beams_only}));

// upbp's photon beams (B-B1D) as the only estimator in the medium (no connections, no photon
// points, no query beams: every path with a medium vertex is a photon beam gathered by a camera
// segment), short and long, with either MIS constant; chromatic and anisotropic media. Long
// beams cross the whole furnace sphere, and a diagonal beam's box is large, so each query
// visits many: they get fewer iterations (measured on the loaded machine: 55 s at 256
// iterations, 128 s with sigma_t 4 and backward HG). The case sigma_t 4 with backward HG once
// read 3.6 % bright at radius 0.02 as 8 standard errors: those were the pixels' spread, which
// the shared beams make about 6x too small; from 16 batches the same render is 1.0363 +- 0.026
// (1.4 SE), and the same seed at radii 0.005-0.04 (paired batches) differs by at most 2 paired
// standard errors (0.2-1 %) with no trend, for backward, isotropic and forward HG (docs/
// media.md, "Photon beams"): no visible kernel bias, so it runs at 0.02 like the others. Batch
// standard errors here: 0.008, 0.010, 0.014 and 0.026 (this case); with a short beam's
// transmittance not divided by its pass probability the short cases read 0.70, 0.74-0.85 and 0.53
// (planted, all failed).
void photon_beams_only(RenderSettings& s) {
    s.vertex_connections = false;
    s.photon_points = false;
    s.query_beams = false;
    s.photon_beams = true;
}
void long_photon_beams_only(RenderSettings& s) {
    photon_beams_only(s);
    s.short_photon_beams = false;
    s.photon_beam_eta = 2.0;
}
// Beams from a quarter of the light paths (--photon-beam-paths 0.25: 64 of the furnace's 256):
// the estimate normalised by those 64, not by all 256 (which would read 0.25).
void photon_beams_only_from_a_quarter_of_the_paths(RenderSettings& s) {
    photon_beams_only(s);
    s.photon_beam_paths = 0.25;
}
INSTANTIATE_TEST_SUITE_P(
    PhotonBeams, MediumFurnace,
    ::testing::Values(
        FurnaceCase{"upbp", "1", kIsotropic, true, 0.02, 256, true, photon_beams_only},
        FurnaceCase{"upbp", "1", kIsotropic, true, 0.02, 512, true,
                    photon_beams_only_from_a_quarter_of_the_paths},
        FurnaceCase{"upbp", "1", kIsotropic, true, 0.02, 64, true, long_photon_beams_only},
        FurnaceCase{"upbp", "0.3, 1, 3", kForward, true, 0.02, 256, true, photon_beams_only},
        FurnaceCase{"upbp", "4", kBackward, true, 0.02, 256, true, photon_beams_only}));

// --- single scattering in an infinite medium -------------------------------------------------

constexpr double kLightX = 0.6, kLightZ = 2.0;  // point light at (0.6, 0, 2); camera looks down +z

std::string infinite_medium(const std::string& sigma_t, const std::string& albedo, double g) {
    char light[160];
    std::snprintf(light, sizeof light, R"(<point name="position" x="%g" y="0" z="%g"/>)", kLightX,
                  kLightZ);
    return R"(<scene version="3.0.0">
  <medium type="homogeneous" id="fog">
    <rgb name="sigma_t" value=")" +
           sigma_t + R"("/>
    <rgb name="albedo" value=")" +
           albedo + R"("/>
    <phase type="hg"><float name="g" value=")" +
           std::to_string(g) + R"("/></phase>
  </medium>
  <sensor type="perspective">
    <float name="fov" value="0.0001"/>
    <transform name="to_world"><lookat origin="0, 0, 0" target="0, 0, 1" up="0, 1, 0"/></transform>
    <film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="8"/></film>
    <ref id="fog"/>
  </sensor>
  <emitter type="point">)" +
           std::string(light) + R"(<rgb name="intensity" value="10"/></emitter>
</scene>)";
}

// Single-scattered radiance along the ray from the origin in +z: the integral over t of
// sigma_s T(t) p(theta) I T(r) / r^2, with t = delta + D tan(theta) (the equi-angular change of
// variables makes the integrand smooth), by composite Simpson on 200001 nodes.
double single_scattering(double sigma_t, double albedo, double g, double intensity) {
    const double delta = kLightZ, d = kLightX;
    const double a = std::atan(-delta / d), b = 0.5 * M_PI;
    const int n = 200000;
    const double h = (b - a) / n;
    auto f = [&](double theta) {
        if (theta >= b) return 0.0;
        const double t = delta + d * std::tan(theta);
        const double r2 = d * d + (t - delta) * (t - delta), r = std::sqrt(r2);
        const double cos_theta = (delta - t) / r;  // between the ray and the direction to the light
        const double denom = 1 + g * g - 2 * g * cos_theta;
        const double phase = (1 - g * g) / (4 * M_PI * denom * std::sqrt(denom));
        const double dt = d / (std::cos(theta) * std::cos(theta));
        return sigma_t * albedo * std::exp(-sigma_t * (t + r)) * phase * intensity / r2 * dt;
    };
    double sum = f(a) + f(b);
    for (int i = 1; i < n; ++i) sum += f(a + i * h) * (i % 2 ? 4 : 2);
    return sum * h / 3;
}

struct SingleScatteringCase {
    bool equiangular;
    double g;
};

class SingleScattering : public ::testing::TestWithParam<SingleScatteringCase> {};

TEST_P(SingleScattering, MatchesTheIntegral) {
    const SingleScatteringCase& c = GetParam();
    // Chromatic: each channel has its own extinction and albedo (spectral MIS in medium.h).
    const double sigma_t[3] = {0.3, 0.8, 2.0}, albedo[3] = {0.9, 0.5, 0.7};
    // max_depth 2: camera segment plus the segment to the light, i.e. single scattering only.
    IterationResult r = render(infinite_medium("0.3, 0.8, 2", "0.9, 0.5, 0.7", c.g), "volpt",
                               c.equiangular ? 400 : 4000, c.equiangular, 2);
    EXPECT_EQ(r.stats.non_finite, 0u);
    for (int channel = 0; channel < 3; ++channel) {
        const double expected = single_scattering(sigma_t[channel], albedo[channel], c.g, 10.0);
        const PixelStatistics s = pixel_statistics(r, channel);
        ASSERT_GT(expected, 0.0);
        ASSERT_GT(s.standard_error, 0.0);
        // 5 standard errors; and a standard error of at most 2 %, so that a test with a huge
        // standard error cannot pass by accident.
        EXPECT_NEAR(s.mean, expected, 5 * s.standard_error)
            << "channel " << channel << " equiangular " << c.equiangular << " g " << c.g;
        EXPECT_LT(s.standard_error, 0.02 * expected) << "channel " << channel;
    }
}

INSTANTIATE_TEST_SUITE_P(PointLight, SingleScattering,
                         ::testing::Values(SingleScatteringCase{true, 0.0},
                                           SingleScatteringCase{false, 0.0},
                                           SingleScatteringCase{true, 0.6},
                                           SingleScatteringCase{true, -0.4}));

// --- hard cases ---------------------------------------------------------------------------------

// An index-matched sphere of medium between the camera and a large emitter behind it.
std::string sphere_in_front_of_light(const std::string& sigma_t, const std::string& albedo) {
    return R"(<scene version="3.0.0">
  <medium type="homogeneous" id="blob">
    <rgb name="sigma_t" value=")" +
           sigma_t + R"("/>
    <float name="albedo" value=")" +
           albedo + R"("/>
  </medium>
  <sensor type="perspective">
    <float name="fov" value="10"/>
    <transform name="to_world"><lookat origin="0, 0, -5" target="0, 0, 0" up="0, 1, 0"/></transform>
    <film type="hdrfilm"><integer name="width" value="16"/><integer name="height" value="16"/></film>
  </sensor>
  <shape type="sphere">
    <float name="radius" value="1"/>
    <bsdf type="null"/>
    <ref name="interior" id="blob"/>
  </shape>
  <shape type="rectangle">
    <transform name="to_world"><scale value="10"/><rotate y="1" angle="180"/><translate z="3"/></transform>
    <emitter type="area"><rgb name="radiance" value="1"/></emitter>
  </shape>
</scene>)";
}

TEST(HardCases, DenseMediumBlocksTheLight) {
    // sigma_t * diameter = 2e4: the sphere fills the view (fov 10 degrees at distance 5), and
    // no light gets through or is scattered back (albedo 0.5, lit from behind only).
    IterationResult r = render(sphere_in_front_of_light("1e4", "0.5"), "volpt", 8);
    EXPECT_EQ(r.stats.non_finite, 0u);
    for (int channel = 0; channel < 3; ++channel)
        EXPECT_LT(pixel_statistics(r, channel).mean, 1e-6);
}

TEST(HardCases, ThinMediumIsInvisible) {
    // sigma_t * diameter = 2e-7: transmittance 1 - 2e-7, so the emitter (radiance 1) is seen
    // through the sphere unchanged to float precision.
    IterationResult r = render(sphere_in_front_of_light("1e-7", "0.5"), "volpt", 4);
    EXPECT_EQ(r.stats.non_finite, 0u);
    for (int channel = 0; channel < 3; ++channel)
        EXPECT_NEAR(pixel_statistics(r, channel).mean, 1.0, 1e-5);
}

TEST(HardCases, GrazingRaysAtTheMediumBoundaryStayFinite) {
    // The sphere's silhouette fills the image: every camera ray is within a fraction of a
    // degree of tangent to the boundary, crossing it at grazing angles (or just missing it).
    std::string xml = sphere_in_front_of_light("3", "0.9");
    const std::string narrow = R"(<float name="fov" value="10"/>)";
    xml.replace(xml.find(narrow), narrow.size(), R"(<float name="fov" value="0.05"/>)");
    const std::string at_centre = R"(target="0, 0, 0")";
    // Aim at the silhouette seen from (0, 0, -5): the tangent makes asin(1/5) with the axis,
    // so it meets the plane z = 0 at y = 5 tan(asin(0.2)) = 1.0206207.
    xml.replace(xml.find(at_centre), at_centre.size(), R"(target="0, 1.0206207, 0")");
    IterationResult r = render(xml, "volpt", 16);
    EXPECT_EQ(r.stats.non_finite, 0u);
    for (int channel = 0; channel < 3; ++channel) {
        const double mean = pixel_statistics(r, channel).mean;
        EXPECT_GT(mean, 0.0);
        EXPECT_LE(mean, 1.0 + 1e-3);  // a lit medium of albedo < 1 cannot brighten the light
    }
}

TEST(HardCases, AlbedoOneWithUnboundedDepthTerminates) {
    // sigma_t R = 30 and albedo 1 in the furnace: without Russian roulette a path would scatter
    // about 900 times before escaping; with it every path ends, and the estimate stays unbiased.
    IterationResult r =
        render(medium_furnace("30", R"(<phase type="isotropic"/>)"), "volpt", 16, true, -1);
    EXPECT_EQ(r.stats.non_finite, 0u);
    const PixelStatistics s = pixel_statistics(r, 1);
    ASSERT_GT(s.standard_error, 0.0);
    EXPECT_NEAR(s.mean, 1.0, 5 * s.standard_error);
}

// Joint sampling (volpt's J3, bpt's J1 connections) at the extremes of optical thickness (the
// fog box's extinction scaled so that its 4-unit width is 1e-6 or 1e3 mean free paths) and of
// anisotropy (g = +-0.99): no sample is NaN or infinite, and the image is what those media must
// give: the thin box shows the point light's single scattering (positive, finite), the dense one
// nothing (the light is 475 mean free paths from the camera).
TEST(HardCases, JointSamplingAtExtremeThicknessAndAnisotropyStaysFinite) {
    struct Case {
        const char* sigma_t;
        const char* g;
        bool dark;
        // bpt and vcm sample medium vertices by distance only (J1 needs a light vertex in the
        // medium): in 8 iterations of the thin box they find none, and their image is black.
        bool thin = false;
    };
    for (const Case& k : {Case{"2.5e-7", "0", false, true}, Case{"250", "0", true},
                          Case{"0.5", "0.99", false}, Case{"0.5", "-0.99", false}}) {
        auto scene =
            load_scene(std::string(RENDER_SOURCE_DIR) + "/scenes/tests/fog-box.xml",
                       {{"resx", "16"}, {"resy", "16"}, {"g", k.g}, {"sigma_t", k.sigma_t}});
        for (const char* algorithm : {"volpt", "bpt", "vcm"}) {
            SCOPED_TRACE(::testing::Message()
                         << algorithm << " sigma_t " << k.sigma_t << " g " << k.g);
            const bool volpt = std::string(algorithm) == "volpt";
            const std::string joint = volpt ? "jis" : "joint_connections";
            RenderSettings settings =
                resolve_render_settings(algorithm, {{joint, "on"}}, scene->settings);
            settings.seed = 1234;
            const IterationResult r = render_iterations(*scene, settings, 0, IterationRange{1, 9});
            EXPECT_EQ(r.stats.non_finite, 0u);
            for (int channel = 0; channel < 3; ++channel) {
                const double mean = pixel_statistics(r, channel).mean;
                ASSERT_TRUE(std::isfinite(mean));
                if (k.dark) {
                    EXPECT_LT(mean, 1e-30);
                } else if (volpt || !k.thin) {
                    EXPECT_GT(mean, 0.0);
                }
            }
        }
    }
}

// bpt's J2 connections (--joint-connections all) in the same hard cases: the fog box's emission
// rays start in the medium (point light), so every eye segment resamples the pixel's first light
// vertex by B2 over the whole bounding sphere. No sample is NaN or infinite; the dense box is
// black, the g = +-0.99 boxes are lit (the thin box: see above, bpt finds no medium vertex there
// in 8 iterations without J2; with J2 it may, so only finiteness is required).
TEST(HardCases, JointSegmentConnectionsAtExtremeThicknessAndAnisotropyStayFinite) {
    struct Case {
        const char* sigma_t;
        const char* g;
        bool dark, lit;
    };
    for (const Case& k : {Case{"2.5e-7", "0", false, false}, Case{"250", "0", true, false},
                          Case{"0.5", "0.99", false, true}, Case{"0.5", "-0.99", false, true}}) {
        SCOPED_TRACE(::testing::Message() << "sigma_t " << k.sigma_t << " g " << k.g);
        auto scene =
            load_scene(std::string(RENDER_SOURCE_DIR) + "/scenes/tests/fog-box.xml",
                       {{"resx", "16"}, {"resy", "16"}, {"g", k.g}, {"sigma_t", k.sigma_t}});
        RenderSettings settings =
            resolve_render_settings("bpt", {{"joint_connections", "all"}}, scene->settings);
        ASSERT_TRUE(settings.joint2_connections);
        settings.seed = 1234;
        const IterationResult r = render_iterations(*scene, settings, 0, IterationRange{1, 9});
        EXPECT_EQ(r.stats.non_finite, 0u);
        for (int channel = 0; channel < 3; ++channel) {
            const double mean = pixel_statistics(r, channel).mean;
            ASSERT_TRUE(std::isfinite(mean));
            if (k.dark) {
                EXPECT_LT(mean, 1e-30);
            }
            if (k.lit) {
                EXPECT_GT(mean, 0.0);
            }
        }
    }
}

// Query beams (upbp, with every estimator and as the only one in the medium) at the extremes of
// optical thickness: a sphere 2e4 mean free paths across in front of the light shows nothing,
// one 2e-7 across shows the light unchanged; in the fog box scaled to 1e-6 and 1e3 mean free
// paths no sample is NaN or infinite, and the dense box is black. The query of a camera ray
// through the dense sphere is long in space and 1e4 mean free paths deep: its transmittance
// and distance densities underflow, which the weights must survive (vcm_mis.h,
// weight_query_beam).
// Photon beams (short and long, as the only medium estimator) go through the same cases: a
// beam through the dense sphere is 1e4 mean free paths deep, through the thin one 1e-7.
TEST(HardCases, QueryBeamsAtExtremeThicknessStayFinite) {
    for (void (*adjust)(RenderSettings&) :
         {+[](RenderSettings&) {}, query_beams_only, photon_beams_only, long_photon_beams_only}) {
        IterationResult dense =
            render(sphere_in_front_of_light("1e4", "0.5"), "upbp", 4, true, -1, 0.02, true, adjust);
        IterationResult thin = render(sphere_in_front_of_light("1e-7", "0.5"), "upbp", 4, true, -1,
                                      0.02, true, adjust);
        EXPECT_EQ(dense.stats.non_finite + thin.stats.non_finite, 0u);
        for (int channel = 0; channel < 3; ++channel) {
            EXPECT_LT(pixel_statistics(dense, channel).mean, 1e-6);
            EXPECT_NEAR(pixel_statistics(thin, channel).mean, 1.0, 1e-5);
        }
        for (const char* sigma_t : {"2.5e-7", "250"}) {
            auto scene = load_scene(std::string(RENDER_SOURCE_DIR) + "/scenes/tests/fog-box.xml",
                                    {{"resx", "16"}, {"resy", "16"}, {"sigma_t", sigma_t}});
            RenderSettings settings = resolve_render_settings("upbp", {}, scene->settings);
            settings.seed = 1234;
            testing::beams_from_every_path(settings);
            adjust(settings);
            const IterationResult r = render_iterations(*scene, settings, 0, IterationRange{1, 9});
            EXPECT_EQ(r.stats.non_finite, 0u) << sigma_t;
            for (int channel = 0; channel < 3; ++channel) {
                const double mean = pixel_statistics(r, channel).mean;
                ASSERT_TRUE(std::isfinite(mean)) << sigma_t;
                if (std::string(sigma_t) == "250") {
                    EXPECT_LT(mean, 1e-30);
                }
            }
        }
    }
}

TEST(MediaSupport, SurfaceOnlyAlgorithmsRefuseMediaScenes) {
    auto scene = load_scene_from_string(medium_furnace("1", ""), ".");
    for (const char* algorithm : {"pt", "eyelight"}) {
        RenderSettings settings;
        settings.algorithm = algorithm;
        EXPECT_THROW(render_iterations(*scene, settings, 0, IterationRange{1, 2}),
                     std::invalid_argument)
            << algorithm;
    }
}

}  // namespace
}  // namespace render
