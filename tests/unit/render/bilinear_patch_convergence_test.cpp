// Non-planar bilinear patches in images (scenes/tests/bilinear.pbrt: a saddle lit by a twisted
// patch that is an area light). Two block tests (convergence_test.cpp's: 32 batches, 4 x 4
// blocks per image and channel, the standard error of each block mean from the spread of its
// batch means; a difference beyond k = 5 combined standard errors fails, P ~ 2e-5 per
// comparison with 31 degrees of freedom):
//   - the saddle as a patch equals the saddle as a 128 x 128 tessellated triangle mesh (the
//     tessellation's error, ~1e-5 of the scene, is far below the noise), while the two
//     triangles through its corners differ;
//   - light tracing and BPT equal path tracing: they sample the emitting patch by its bilinear
//     warp (emit, illuminate) and find its density back at hits (AreaLight::radiance).

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <memory>
#include <sstream>
#include <string>

#include "core/render/render_options.h"
#include "core/scene/pbrt/scene_loader.h"
#include "tests/support/block_estimate.h"

namespace render {
namespace {

const std::string kDir = std::string(RENDER_SOURCE_DIR) + "/scenes/tests";
const std::string kSaddle =
    R"(Shape "bilinearmesh" "point3 P" [-0.8 0.2 -0.5  -0.8 0.9 0.5  0.8 0.9 -0.5  0.8 0.2 0.5])";

// The shipped scene at 32 x 32 (the block test needs a square film), with the saddle's shape
// replaced by `saddle` if given.
std::unique_ptr<Scene> bilinear_scene(const std::string& saddle = "") {
    std::ifstream in(kDir + "/bilinear.pbrt");
    std::stringstream text;
    text << in.rdbuf();
    std::string scene = text.str();
    for (const auto& [from, to] : {std::pair<std::string, std::string>{
                                       R"("integer xresolution" [128] "integer yresolution" [96])",
                                       R"("integer xresolution" [32] "integer yresolution" [32])"},
                                   {kSaddle, saddle.empty() ? kSaddle : saddle}}) {
        const size_t at = scene.find(from);
        EXPECT_NE(at, std::string::npos) << from;
        if (at == std::string::npos) return nullptr;
        scene.replace(at, from.size(), to);
    }
    return pbrt::load_scene_from_string(scene, kDir);
}

// The saddle as an n x n grid of quads, two triangles each, with the patch's winding.
std::string tessellated_saddle(int n) {
    const float p[4][3] = {
        {-0.8f, 0.2f, -0.5f}, {-0.8f, 0.9f, 0.5f}, {0.8f, 0.9f, -0.5f}, {0.8f, 0.2f, 0.5f}};
    std::ostringstream out;
    out.precision(9);
    out << R"(Shape "trianglemesh" "point3 P" [)";
    for (int y = 0; y <= n; ++y)
        for (int x = 0; x <= n; ++x) {
            const double u = double(x) / n, v = double(y) / n;
            for (int c = 0; c < 3; ++c)
                out << (1 - v) * ((1 - u) * p[0][c] + u * p[1][c]) +
                           v * ((1 - u) * p[2][c] + u * p[3][c])
                    << ' ';
        }
    out << R"(] "integer indices" [)";
    for (int y = 0; y < n; ++y)
        for (int x = 0; x < n; ++x) {
            const int a = y * (n + 1) + x;
            for (int k : {a, a + 1, a + n + 2, a, a + n + 2, a + n + 1}) out << k << ' ';
        }
    out << "]";
    return out.str();
}

testing::BlockEstimate render_blocks(const Scene& scene, const std::string& algorithm) {
    RenderSettings settings = resolve_render_settings(algorithm, {}, scene.settings);
    settings.seed = 5151;
    return testing::render_block_estimate(scene, settings, 32, 8, 4);
}

TEST(BilinearPatchConvergence, PatchEqualsFineTessellation) {
    auto patch = bilinear_scene();
    auto mesh = bilinear_scene(tessellated_saddle(128));
    auto coarse = bilinear_scene(tessellated_saddle(1));
    ASSERT_TRUE(patch && mesh && coarse);
    const testing::BlockEstimate a = render_blocks(*patch, "pt");
    for (const std::string& d : testing::differing_blocks(a, render_blocks(*mesh, "pt"), 1.0, 5.0))
        ADD_FAILURE() << "patch vs tessellation: " << d;
    // Not vacuous: the two triangles through the corners are resolved as a different surface.
    EXPECT_GE(testing::differing_blocks(a, render_blocks(*coarse, "pt"), 1.0, 5.0).size(), 2u);
}

TEST(BilinearPatchConvergence, EmittingPatchLightTracingAndBptEqualPathTracing) {
    auto scene = bilinear_scene();
    ASSERT_TRUE(scene);
    const testing::BlockEstimate reference = render_blocks(*scene, "pt");
    for (const char* algorithm : {"lt", "bpt"}) {
        SCOPED_TRACE(algorithm);
        const testing::BlockEstimate e = render_blocks(*scene, algorithm);
        for (const std::string& d : testing::differing_blocks(reference, e, 1.0, 5.0))
            ADD_FAILURE() << algorithm << " vs pt: " << d;
        // Not vacuous: the comparison resolves most blocks to 10 % of their mean.
        size_t resolved = 0;
        for (size_t i = 0; i < e.mean.size(); ++i)
            resolved += std::hypot(e.standard_error[i], reference.standard_error[i]) <
                        0.1 * reference.mean[i];
        EXPECT_GE(resolved, e.mean.size() * 3 / 4);
    }
}

}  // namespace
}  // namespace render
