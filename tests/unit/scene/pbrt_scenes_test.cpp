// The shipped pbrt-v4 scenes (scenes/bitterli-pbrt/): the pbrt Cornell box converges to the same
// image as the Mitsuba file of the same scene (scenes/bitterli/cornell-box/scene_v3.xml), and
// the three shipped scenes load and render a few iterations with pt and vcm.
//
// The block test, as tests/unit/render/convergence_test.cpp: each file renders 32 batches of 8
// iterations at 32 x 32 (independent seeds: 11 for pbrt, 22 for Mitsuba, so the two estimates
// are independent and the test is a statistical one, not a comparison of identical paths).
// Block means (4 x 4 blocks of 8 x 8 pixels, per channel) get a standard error from the spread
// of their 32 batch means (31 degrees of freedom); a difference beyond k = 5 combined standard
// errors fails. With Student-t tails P(|t| > 5) ~ 2e-5 per comparison, ~1e-3 over the 48
// comparisons, and the seeds are fixed, so a pass is reproducible. That the test can fail is
// checked on the same estimates: a 3 % brighter light (every block scaled by 1.03) fails it.
//
// The files differ in one thing the test accepts: pbrt's maxdepth 65 is our max_depth 66
// (pbrt counts bounces, we count segments), the Mitsuba file's max_depth is 65; paths of 65
// segments carry about 0.7^64 ~ 1e-10 of the image.

#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "core/render/render_iterations.h"
#include "core/render/render_options.h"
#include "core/scene/loader/scene_loader.h"
#include "core/scene/pbrt/scene_loader.h"
#include "tests/support/block_estimate.h"
#include "tests/support/statistics.h"

namespace render {
namespace {

constexpr int kResolution = 32;
constexpr int kBlocksPerSide = 4;
constexpr int kBatches = 32;
constexpr int kIterationsPerBatch = 8;
constexpr double kStandardErrors = 5.0;

const std::string kScenes = std::string(RENDER_SOURCE_DIR) + "/scenes/";

using testing::BlockEstimate;

std::unique_ptr<Scene> load_small(const std::string& file, int resolution) {
    std::unique_ptr<Scene> scene = load_scene(kScenes + file);
    scene->set_camera(scene->camera().with_resolution(resolution, resolution));
    return scene;
}

BlockEstimate render_blocks(const Scene& scene, uint64_t seed) {
    RenderSettings settings = resolve_render_settings("pt", {}, scene.settings);
    settings.seed = seed;
    return testing::render_block_estimate(scene, settings, kBatches, kIterationsPerBatch,
                                          kBlocksPerSide);
}

TEST(PbrtScenes, CornellBoxConvergesToTheMitsubaImage) {
    auto pbrt_scene = load_small("bitterli-pbrt/cornell-box/scene-v4.pbrt", kResolution);
    auto mitsuba_scene = load_small("bitterli/cornell-box/scene_v3.xml", kResolution);
    EXPECT_EQ(pbrt_scene->settings.max_depth, 66);
    EXPECT_EQ(mitsuba_scene->settings.max_depth, 65);
    EXPECT_EQ(pbrt_scene->settings.sample_count, 512);
    const BlockEstimate pbrt = render_blocks(*pbrt_scene, 11);
    const BlockEstimate mitsuba = render_blocks(*mitsuba_scene, 22);
    for (size_t i = 0; i < pbrt.mean.size(); ++i) {
        ASSERT_GT(pbrt.standard_error[i], 0.0) << "block value " << i << " has no noise";
    }
    const std::vector<std::string> differ =
        testing::differing_blocks(pbrt, mitsuba, 1.0, kStandardErrors);
    EXPECT_TRUE(differ.empty()) << differ.size() << " block values differ, first: " << differ[0];
    // The comparison can fail: a 3 % brighter Mitsuba image differs in some block.
    EXPECT_FALSE(testing::differing_blocks(pbrt, mitsuba, 1.03, kStandardErrors).empty());
}

// Each shipped pbrt scene loads and renders 2 iterations at 16 x 16 with pt and vcm: finite
// pixels and some light.
TEST(PbrtScenes, ShippedScenesRenderWithPtAndVcm) {
    for (const char* file :
         {"bitterli-pbrt/cornell-box/scene-v4.pbrt", "bitterli-pbrt/water-caustic/scene-v4.pbrt",
          "bitterli-pbrt/coffee/scene-v4.pbrt"}) {
        auto scene = load_small(file, 16);
        for (const char* algorithm : {"pt", "vcm"}) {
            RenderSettings settings = resolve_render_settings(algorithm, {}, scene->settings);
            settings.seed = 5;
            IterationResult r = render_iterations(*scene, settings, 0, IterationRange{1, 3});
            EXPECT_EQ(r.stats.non_finite, 0u) << file << " " << algorithm;
            double total = 0;
            for (size_t p = 0; p < 16 * 16; ++p)
                for (int c = 0; c < 3; ++c) total += r.sum.channel(p, c);
            EXPECT_GT(total, 0.0) << file << " " << algorithm;
            EXPECT_TRUE(std::isfinite(total)) << file << " " << algorithm;
        }
    }
}

// scenes/tests/ply-quads.pbrt is bilinear.pbrt with its two non-planar patches read from PLY
// quads: the same shapes, lights and random numbers, so the same image bit for bit, with pt and
// bpt (a quad read in the file's order instead of pbrt-v4's v0 v1 v3 v2 would be another
// surface, or kept as triangles another image).
TEST(PbrtScenes, PlyQuadsRenderAsTheirBilinearMesh) {
    auto quads = load_small("tests/ply-quads.pbrt", 16);
    auto patches = load_small("tests/bilinear.pbrt", 16);
    for (const char* algorithm : {"pt", "bpt"}) {
        RenderSettings settings = resolve_render_settings(algorithm, {}, quads->settings);
        settings.seed = 9;
        const IterationResult a = render_iterations(*quads, settings, 0, IterationRange{1, 3});
        const IterationResult b = render_iterations(*patches, settings, 0, IterationRange{1, 3});
        double total = 0;
        int differing = 0;
        for (size_t p = 0; p < 16 * 16; ++p)
            for (int c = 0; c < 3; ++c) {
                total += a.sum.channel(p, c);
                differing += a.sum.channel(p, c) != b.sum.channel(p, c);
            }
        EXPECT_GT(total, 0.0) << algorithm;
        EXPECT_EQ(differing, 0) << algorithm;
    }
}

// The same small scene in both formats (floor, a gold and a glass sphere, a coated disk, a point
// light and a constant environment; a 32 x 24 film with fov on the shorter axis; pbrt's
// `Scale -1 1 1` before LookAt, which gives Mitsuba's image orientation) builds the same
// objects, so with the same seed the two renders draw the same random numbers for the same
// paths: the images agree up to float rounding in the transforms, which can move a ray across
// an edge. Checked: the total differs by < 1e-3 relative, and fewer than 3 % of the pixels
// differ by more than 1 % (a mirrored image, a wrong fov axis, another material or light
// would change most of them).
TEST(PbrtScenes, SmallSceneMatchesItsMitsubaTwin) {
    const std::string pbrt_text = R"(
Integrator "path" "integer maxdepth" 4
Sampler "independent" "integer pixelsamples" 8
Film "rgb" "integer xresolution" 32 "integer yresolution" 24
Scale -1 1 1
LookAt 0 1.5 6  0 0.8 0  0 1 0
Camera "perspective" "float fov" 40
WorldBegin
LightSource "point" "rgb I" [10 10 10] "point3 from" [1 3 2]
LightSource "infinite" "rgb L" [0.2 0.3 0.4]
Material "diffuse" "rgb reflectance" [0.6 0.6 0.5]
Shape "trianglemesh" "point3 P" [-3 0 -3  -3 0 3  3 0 3  3 0 -3] "integer indices" [0 1 2 0 2 3]
AttributeBegin
  Translate -1 0.7 0
  Material "conductor" "spectrum eta" "metal-Au-eta" "spectrum k" "metal-Au-k"
  Shape "sphere" "float radius" 0.7
AttributeEnd
AttributeBegin
  Translate 1 0.7 0.5
  Material "dielectric" "float eta" 1.5
  Shape "sphere" "float radius" 0.7
AttributeEnd
AttributeBegin
  Translate 0 1 -2
  Material "coateddiffuse" "rgb reflectance" [0.2 0.5 0.8]
  Shape "disk" "float radius" 1
AttributeEnd
)";
    const std::string mitsuba_text = R"(<scene version="3.0.0">
  <integrator type="path"><integer name="max_depth" value="5"/></integrator>
  <sensor type="perspective">
    <float name="fov" value="40"/><string name="fov_axis" value="smaller"/>
    <transform name="to_world"><lookat origin="0, 1.5, 6" target="0, 0.8, 0" up="0, 1, 0"/></transform>
    <sampler type="independent"><integer name="sample_count" value="8"/></sampler>
    <film type="hdrfilm"><integer name="width" value="32"/><integer name="height" value="24"/></film>
  </sensor>
  <emitter type="point"><point name="position" x="1" y="3" z="2"/><rgb name="intensity" value="10"/></emitter>
  <emitter type="constant"><rgb name="radiance" value="0.2, 0.3, 0.4"/></emitter>
  <shape type="rectangle">
    <transform name="to_world"><scale value="3"/><rotate x="1" angle="-90"/></transform>
    <bsdf type="twosided"><bsdf type="diffuse"><rgb name="reflectance" value="0.6, 0.6, 0.5"/></bsdf></bsdf>
  </shape>
  <shape type="sphere"><point name="center" x="-1" y="0.7" z="0"/><float name="radius" value="0.7"/>
    <bsdf type="twosided"><bsdf type="conductor"><string name="material" value="Au"/></bsdf></bsdf>
  </shape>
  <shape type="sphere"><point name="center" x="1" y="0.7" z="0.5"/><float name="radius" value="0.7"/>
    <bsdf type="dielectric"><float name="int_ior" value="1.5"/><float name="ext_ior" value="1"/></bsdf>
  </shape>
  <shape type="disk">
    <transform name="to_world"><translate x="0" y="1" z="-2"/></transform>
    <bsdf type="twosided"><bsdf type="plastic"><rgb name="diffuse_reflectance" value="0.2, 0.5, 0.8"/>
      <float name="int_ior" value="1.5"/><float name="ext_ior" value="1"/><boolean name="nonlinear" value="true"/></bsdf></bsdf>
  </shape>
</scene>)";
    auto from_pbrt = pbrt::load_scene_from_string(pbrt_text, ".");
    auto from_mitsuba = load_scene_from_string(mitsuba_text, ".");
    EXPECT_EQ(from_pbrt->settings.max_depth, from_mitsuba->settings.max_depth);
    auto image = [](const Scene& scene) {
        RenderSettings settings = resolve_render_settings("pt", {}, scene.settings);
        settings.seed = 7;
        return render_iterations(scene, settings, 0, IterationRange{1, 9});
    };
    const IterationResult a = image(*from_pbrt), b = image(*from_mitsuba);
    double total_a = 0, total_b = 0, total_diff = 0;
    int differing = 0;
    const int pixels = 32 * 24;
    for (int p = 0; p < pixels; ++p) {
        double pa = 0, pb = 0;
        for (int c = 0; c < 3; ++c) {
            pa += a.sum.channel(size_t(p), c);
            pb += b.sum.channel(size_t(p), c);
        }
        total_a += pa, total_b += pb, total_diff += std::abs(pa - pb);
        if (std::abs(pa - pb) > 0.01 * std::max(pa, pb) + 1e-6) ++differing;
    }
    EXPECT_GT(total_a, 0.0);
    EXPECT_LT(std::abs(total_a - total_b), 1e-3 * total_b);
    EXPECT_LT(differing, pixels * 3 / 100) << "of " << pixels << " pixels; |a - b| sums to "
                                           << total_diff / total_b << " of the image";
}

// A pbrt file with both media types (a homogeneous sphere and a grid sphere, with the interface
// material) renders with volpt: finite, lit, and the media absorb (darker than without them).
TEST(PbrtScenes, MediaRenderWithVolpt) {
    const std::string head =
        "LookAt 0 0 -4  0 0 0  0 1 0\nCamera \"perspective\" \"float fov\" 50\n"
        "Film \"rgb\" \"integer xresolution\" 16 \"integer yresolution\" 16\nWorldBegin\n"
        "LightSource \"infinite\" \"rgb L\" [1 1 1]\n";
    const std::string media =
        "MakeNamedMedium \"fog\" \"string type\" \"homogeneous\" \"rgb sigma_a\" [1 1 1] "
        "\"rgb sigma_s\" [1 1 1] \"float g\" 0.3\n"
        "MakeNamedMedium \"grid\" \"string type\" \"uniformgrid\" \"integer nx\" 2 "
        "\"integer ny\" 2 \"float density\" [0 1 2 3] \"point3 p0\" [-1 -1 -1] \"point3 p1\" "
        "[1 1 1]\n";
    const std::string shapes =
        "AttributeBegin\nMediumInterface \"fog\" \"\"\nMaterial \"interface\"\n"
        "Translate -1 0 0\nShape \"sphere\" \"float radius\" 0.8\nAttributeEnd\n"
        "AttributeBegin\nMediumInterface \"grid\" \"\"\nMaterial \"interface\"\nTranslate 1 0 0\n"
        "Shape \"sphere\" \"float radius\" 0.8\nAttributeEnd\n";
    auto total = [](const Scene& scene) {
        RenderSettings settings = resolve_render_settings("volpt", {}, scene.settings);
        settings.seed = 3;
        IterationResult r = render_iterations(scene, settings, 0, IterationRange{1, 9});
        EXPECT_EQ(r.stats.non_finite, 0u);
        double sum = 0;
        for (size_t p = 0; p < 16 * 16; ++p)
            for (int c = 0; c < 3; ++c) sum += r.sum.channel(p, c);
        return sum;
    };
    auto with_media = pbrt::load_scene_from_string(head + media + shapes, ".");
    EXPECT_TRUE(with_media->has_media());
    auto without = pbrt::load_scene_from_string(head, ".");
    const double a = total(*with_media), b = total(*without);
    EXPECT_GT(a, 0.0);
    EXPECT_LT(a, 0.9 * b);
}

}  // namespace
}  // namespace render
