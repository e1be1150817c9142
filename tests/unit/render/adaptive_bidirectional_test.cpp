// Adaptive sampling in the bidirectional and many-light families
// (docs/reference/adaptive-sampling.md, "The bidirectional family"): eye subpaths from the active
// pixels only, the light pass whole, the light tracer's splats into inactive pixels dropped.

#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "tests/unit/render/adaptive_renders.h"

namespace render {
namespace {

using adaptive_test::adaptive_settings;
using adaptive_test::cornell_box;

constexpr int kSize = 16;

std::unique_ptr<Scene> isosph(int size) {
    auto scene = load_scene(std::string(RENDER_SOURCE_DIR) + "/scenes/smallupbp/isosph.xml",
                            {{"resx", std::to_string(size)}, {"resy", std::to_string(size)}});
    if (scene->camera().width() != size)
        scene->set_camera(scene->camera().with_resolution(size, size));
    return scene;
}

// With a mask, an active pixel's value in an iteration is bit for bit the uniform render's
// value of that iteration (its eye subpath, the splats that land on it, its connections and
// merges with the whole light pass) and an inactive pixel's is 0: no eye subpath, and the
// splats that land on it dropped. The uniform image must be non-zero on inactive pixels (else
// dropping proves nothing), and for the algorithms that splat (lt, and the light vertices'
// camera connections of bpt, vcm and upbp) the splats alone must reach them: the uniform
// render's t = 1 layers are non-zero there.
void expect_masked_iteration_keeps_active_values(const Scene& scene, const std::string& algorithm) {
    SCOPED_TRACE(algorithm);
    RenderSettings uniform = adaptive_settings(7, 0, algorithm);
    RenderSettings adaptive = adaptive_settings(7, 0.05, algorithm);
    // A wide merging radius: with 256 photons the default one leaves the Cornell box nearly
    // black for ppm and bpm.
    uniform.radius_factor = adaptive.radius_factor = 0.05;
    const uint64_t i = adaptive.adaptive_min_iterations + 1;  // round 1
    const size_t pixels = size_t(scene.camera().width()) * scene.camera().height();
    std::vector<uint8_t> mask(pixels);
    for (size_t p = 0; p < pixels; ++p) mask[p] = (p * 7919) % 3 == 0;
    const IterationResult all = render_iterations(scene, uniform, 0, {i, i + 1});
    IterationRenderer renderer(scene, adaptive, 0);
    IterationResult some = renderer.empty_result();
    renderer.add({i, i + 1}, some, mask);
    size_t active_nonzero = 0, inactive_nonzero = 0;
    for (size_t p = 0; p < pixels; ++p)
        for (int c = 0; c < 3; ++c) {
            const double value = all.sum.channel(p, c);
            const double expected = mask[p] ? value : 0.0;
            ASSERT_EQ(some.sum.channel(p, c), expected) << "pixel " << p << " channel " << c;
            (mask[p] ? active_nonzero : inactive_nonzero) += value != 0.0;
        }
    EXPECT_GT(active_nonzero, pixels / 8) << "a black image proves nothing";
    EXPECT_GT(inactive_nonzero, pixels / 4) << "the inactive pixels must have had a value";
    // Each active pixel is one sample, whatever the splats.
    size_t active = 0;
    for (uint8_t m : mask) active += m;
    EXPECT_EQ(some.stats.samples, active);
    const bool splats =
        algorithm == "lt" || algorithm == "bpt" || algorithm == "vcm" || algorithm == "upbp";
    if (!splats) return;
    // The splats alone reach inactive pixels: the (s, t = 1) layers of a uniform render with
    // per-technique layers.
    RenderSettings st = uniform;
    st.layers = LayerMode::PathVertices;
    const IterationResult layered = render_iterations(scene, st, 0, {i, i + 1});
    size_t splatted_inactive = 0;
    for (size_t l = 0; l < layered.layers.size(); ++l) {
        if (layered.layers.name(l).find("_t1") == std::string::npos) continue;
        for (size_t p = 0; p < pixels; ++p)
            if (!mask[p])
                for (int c = 0; c < 3; ++c)
                    splatted_inactive += layered.layers.buffer(l).channel(p, c) != 0.0;
    }
    EXPECT_GT(splatted_inactive, 0u) << "no light-tracing splat landed on an inactive pixel";
}

TEST(AdaptiveBidirectional, MaskedIterationKeepsTheActivePixelsValues) {
    auto scene = cornell_box(kSize);
    for (const char* algorithm : {"lt", "bpt", "ppm", "bpm", "vcm", "upbp", "vpl", "ic"})
        expect_masked_iteration_keeps_active_values(*scene, algorithm);
}

// upbp's beams and volume merges, bpt's and vcm's connections in a medium.
TEST(AdaptiveBidirectional, MaskedIterationKeepsTheActivePixelsValuesInAMedium) {
    auto scene = isosph(kSize);
    for (const char* algorithm : {"bpt", "vcm", "upbp"})
        expect_masked_iteration_keeps_active_values(*scene, algorithm);
}

// The mask's determinism: the exact sums, the counts and the masks are the same for one process
// and for 1, 2 or 3 workers splitting each round (adaptive_renders.h).
TEST(AdaptiveBidirectional, SameSumsAndCountsForAnySplitBpt) {
    auto scene = cornell_box(kSize);
    adaptive_test::expect_same_for_any_split(*scene, adaptive_settings(3, 0.3, "bpt"));
}

TEST(AdaptiveBidirectional, SameSumsAndCountsForAnySplitVcm) {
    auto scene = cornell_box(kSize);
    adaptive_test::expect_same_for_any_split(*scene, adaptive_settings(3, 0.3, "vcm"));
}

TEST(AdaptiveBidirectional, SameSumsAndCountsForAnySplitLt) {
    auto scene = cornell_box(kSize);
    adaptive_test::expect_same_for_any_split(*scene, adaptive_settings(3, 0.3, "lt"));
}

// bpt: each iteration's value of a pixel is an unbiased estimate of it, whatever the mask (the
// MIS weights of an active pixel's techniques sum to one: none of them is dropped), so the
// adaptive estimator matches a converged uniform bpt render (adaptive_renders.h).
TEST(AdaptiveBidirectional, BptEstimatorMatchesAConvergedUniformRender) {
    auto scene = cornell_box(12);
    adaptive_test::expect_estimator_matches_reference(
        *scene, adaptive_settings(0, 0.3, "bpt"), adaptive_settings(1000, 0, "bpt"), 8192, 48, 24);
}

// vcm: an iteration's value has the kernel bias of that iteration's merge radius, the same as in
// a uniform render. With alpha = 1 the radius is the same in every iteration, so each iteration
// estimates the same blurred image, and the adaptive estimator must match a converged uniform
// vcm render at that radius. The radius is wide (5 % of the scene's radius): at the default
// 0.3 % the merges' MIS weights are so small on this film that vcm's sums and masks equal bpt's
// to the exact sums' resolution, and the test would not see merging at all.
TEST(AdaptiveBidirectional, VcmEstimatorMatchesAConvergedUniformRenderAtItsRadius) {
    auto scene = cornell_box(12);
    RenderSettings adaptive = adaptive_settings(0, 0.3, "vcm");
    adaptive.alpha = 1;
    adaptive.radius_factor = 0.05;
    RenderSettings uniform = adaptive_settings(1000, 0, "vcm");
    uniform.alpha = 1;
    uniform.radius_factor = 0.05;
    adaptive_test::expect_estimator_matches_reference(*scene, adaptive, uniform, 8192, 48, 24);
}

}  // namespace
}  // namespace render
