// With a thin-lens camera (core/camera/perspective_camera.h) light tracing, BPT and VCM connect
// light vertices to a sampled lens point; they must converge to path tracing's image, which
// only generates camera rays. The block test of convergence_test.cpp: 32 batches, 4 x 4 blocks
// per image and channel, the standard error of each block mean from the spread of its batch
// means, a difference beyond k = 5 combined standard errors fails (P ~ 2e-5 per comparison with
// 31 degrees of freedom; 144 comparisons here). The lens blurs enough that the pinhole's image
// differs at this block size (checked too), so light paths that ignored the lens would fail.

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <map>
#include <sstream>
#include <string>

#include "core/render/render_options.h"
#include "core/scene/loader/scene_loader.h"
#include "tests/support/block_estimate.h"

namespace render {
namespace {

constexpr int kResolution = 32;

// The Cornell box seen through a lens of radius 0.5 focused at 4 (in front of the box): every
// surface is blurred, the back wall and the light by ~15 pixels at 32 x 32.
const std::string kDir = std::string(RENDER_SOURCE_DIR) + "/scenes/bitterli/cornell-box";
const std::map<std::string, std::string> kDefines = {{"resx", std::to_string(kResolution)},
                                                     {"resy", std::to_string(kResolution)},
                                                     {"max_depth", "8"}};

std::unique_ptr<Scene> cornell_box_with_lens() {
    const std::string& dir = kDir;
    std::ifstream in(dir + "/scene_v3.xml");
    std::stringstream text;
    text << in.rdbuf();
    std::string xml = text.str();
    const std::string pinhole = R"(<sensor type="perspective">)";
    const size_t at = xml.find(pinhole);
    EXPECT_NE(at, std::string::npos);
    if (at == std::string::npos) return nullptr;
    xml.replace(at, pinhole.size(), R"(<sensor type="thinlens">
        <float name="aperture_radius" value="0.5"/>
        <float name="focus_distance" value="4"/>)");
    return load_scene_from_string(xml, dir, kDefines);
}

testing::BlockEstimate render_blocks(const Scene& scene, const std::string& algorithm,
                                     int iterations_per_batch) {
    RenderSettings settings = resolve_render_settings(algorithm, {}, scene.settings);
    settings.seed = 4321;
    settings.radius_factor = 0.01;  // as convergence_test.cpp: about a pixel at 32 x 32
    return testing::render_block_estimate(scene, settings, 32, iterations_per_batch, 4);
}

TEST(ThinLensConvergence, LightTracingBptAndVcmEqualPathTracing) {
    auto scene = cornell_box_with_lens();
    ASSERT_TRUE(scene);
    ASSERT_TRUE(scene->camera().has_lens());
    const testing::BlockEstimate reference = render_blocks(*scene, "pt", 8);
    // The lens matters at this block size: the pinhole's image differs.
    auto pinhole = load_scene(kDir + "/scene_v3.xml", kDefines);
    EXPECT_GE(
        testing::differing_blocks(reference, render_blocks(*pinhole, "pt", 8), 1.0, 5.0).size(),
        4u);
    for (const char* algorithm : {"lt", "bpt", "vcm"}) {
        SCOPED_TRACE(algorithm);
        const testing::BlockEstimate e = render_blocks(*scene, algorithm, 8);
        for (const std::string& d : testing::differing_blocks(reference, e, 1.0, 5.0))
            ADD_FAILURE() << algorithm << " vs pt: " << d;
        // Not vacuous: the comparison resolves a few percent of every block.
        for (size_t i = 0; i < e.mean.size(); ++i)
            EXPECT_LT(std::hypot(e.standard_error[i], reference.standard_error[i]),
                      0.1 * reference.mean[i])
                << "block " << i / 3 << " channel " << i % 3;
    }
}

}  // namespace
}  // namespace render
