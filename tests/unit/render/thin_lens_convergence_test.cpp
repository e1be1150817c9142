// With a thin-lens camera (core/camera/perspective_camera.h) light tracing, BPT and VCM connect
// light vertices to a sampled lens point; they must converge to path tracing's image, which
// only generates camera rays. The block test of convergence_test.cpp: 32 batches, 2 x 2 blocks
// per image and channel, the standard error of each block mean from the spread of its batch
// means, a difference beyond k = 5 combined standard errors fails (P ~ 2e-5 per comparison with
// 31 degrees of freedom; 36 comparisons here).

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <sstream>
#include <string>

#include "core/render/render_options.h"
#include "core/scene/loader/scene_loader.h"
#include "tests/support/block_estimate.h"

namespace render {
namespace {

constexpr int kResolution = 32;

// The Cornell box seen through a lens of radius 0.2 focused on the tall box's front (5.8 from
// the camera): the back wall, the light and the short box are visibly blurred.
std::unique_ptr<Scene> cornell_box_with_lens() {
    const std::string dir = std::string(RENDER_SOURCE_DIR) + "/scenes/bitterli/cornell-box";
    std::ifstream in(dir + "/scene_v3.xml");
    std::stringstream text;
    text << in.rdbuf();
    std::string xml = text.str();
    const std::string pinhole = R"(<sensor type="perspective">)";
    const size_t at = xml.find(pinhole);
    EXPECT_NE(at, std::string::npos);
    if (at == std::string::npos) return nullptr;
    xml.replace(at, pinhole.size(), R"(<sensor type="thinlens">
        <float name="aperture_radius" value="0.2"/>
        <float name="focus_distance" value="5.8"/>)");
    return load_scene_from_string(xml, dir,
                                  {{"resx", std::to_string(kResolution)},
                                   {"resy", std::to_string(kResolution)},
                                   {"max_depth", "8"}});
}

testing::BlockEstimate render_blocks(const Scene& scene, const std::string& algorithm,
                                     int iterations_per_batch) {
    RenderSettings settings = resolve_render_settings(algorithm, {}, scene.settings);
    settings.seed = 4321;
    settings.radius_factor = 0.01;  // as convergence_test.cpp: about a pixel at 32 x 32
    return testing::render_block_estimate(scene, settings, 32, iterations_per_batch, 2);
}

TEST(ThinLensConvergence, LightTracingBptAndVcmEqualPathTracing) {
    auto scene = cornell_box_with_lens();
    ASSERT_TRUE(scene);
    ASSERT_TRUE(scene->camera().has_lens());
    const testing::BlockEstimate reference = render_blocks(*scene, "pt", 8);
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
