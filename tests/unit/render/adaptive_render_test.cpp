// Adaptive sampling wired into the renderer (docs/reference/adaptive-sampling.md): the same
// sums for any split of the rounds over "workers", per-pixel counts, the pixel loop's mask, and
// the adaptive estimator against a converged uniform render.

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "core/render/render_options.h"
#include "core/scene/scene.h"
#include "tests/unit/render/adaptive_renders.h"

namespace render {
namespace {

using adaptive_test::adaptive_settings;
using adaptive_test::cornell_box;
using adaptive_test::expect_same_for_any_split;
using adaptive_test::render_alone;
using adaptive_test::render_farm;

constexpr int kSize = 16;

TEST(AdaptiveRender, SameSumsAndCountsForAnySplit) {
    auto scene = cornell_box(kSize);
    expect_same_for_any_split(*scene, adaptive_settings(3, 0.3));
}

// volpt in a scene with a homogeneous medium (isosph: a sphere of it under an area light).
TEST(AdaptiveRender, SameSumsAndCountsForAnySplitVolpt) {
    auto scene = load_scene(std::string(RENDER_SOURCE_DIR) + "/scenes/smallupbp/isosph.xml",
                            {{"resx", std::to_string(kSize)}, {"resy", std::to_string(kSize)}});
    if (scene->camera().width() != kSize)
        scene->set_camera(scene->camera().with_resolution(kSize, kSize));
    RenderSettings settings = adaptive_settings(3, 0.3);
    settings.algorithm = "volpt";
    expect_same_for_any_split(*scene, settings);
}

// Each pixel's count is the number of iterations of the rounds whose mask has it active (every
// pixel in the first round), its odd count those of odd index; an inactive pixel's sums do not
// move during the round.
TEST(AdaptiveRender, PerPixelCountsAreTheActiveIterations) {
    auto scene = cornell_box(kSize);
    const RenderSettings settings = adaptive_settings(5, 0.3);
    constexpr uint64_t kIterations = 30;  // the last round is cut short: [29, 31)
    std::vector<std::vector<uint8_t>> masks;
    const IterationResult farm = render_farm(*scene, settings, kIterations, 2, masks);
    const AdaptiveRounds rounds(settings);
    const size_t pixels = size_t(kSize) * kSize;
    std::vector<uint64_t> count(pixels, 0), odd(pixels, 0);
    size_t inactive_seen = 0;
    for (uint64_t round = 0; round < masks.size(); ++round)
        for (uint64_t i = rounds.first(round); i < std::min(rounds.end(round), kIterations + 1);
             ++i)
            for (size_t p = 0; p < pixels; ++p)
                if (round == 0 || masks[round][p]) {
                    ++count[p];
                    if (i % 2 == 1) ++odd[p];
                } else {
                    ++inactive_seen;
                }
    EXPECT_GT(inactive_seen, 0u) << "some pixel must have been inactive for the test to count";
    EXPECT_EQ(farm.adaptive.count, count);
    EXPECT_EQ(farm.adaptive.odd_count, odd);
    // The samples layer is the count.
    const std::vector<NamedLayer> layers = output_layers(farm);
    ASSERT_EQ(layers.size(), 1u);
    EXPECT_EQ(layers[0].name, "samples");
    for (size_t p = 0; p < pixels; ++p) EXPECT_EQ(layers[0].image.at(p).r, float(count[p]));
}

// With a mask, an active pixel's value in an iteration is bit for bit the uniform render's
// value of that iteration and an inactive pixel's is 0: skipping pixels takes no random numbers
// from the others.
TEST(AdaptiveRender, MaskedIterationKeepsTheActivePixelsValues) {
    auto scene = cornell_box(kSize);
    RenderSettings uniform = adaptive_settings(7, 0);
    RenderSettings adaptive = adaptive_settings(7, 0.05);
    const uint64_t i = adaptive.adaptive_min_iterations + 1;  // round 1
    const size_t pixels = size_t(kSize) * kSize;
    std::vector<uint8_t> mask(pixels);
    for (size_t p = 0; p < pixels; ++p) mask[p] = (p * 7919) % 3 == 0;
    const IterationResult all = render_iterations(*scene, uniform, 0, {i, i + 1});
    IterationRenderer renderer(*scene, adaptive, 0);
    IterationResult some = renderer.empty_result();
    renderer.add({i, i + 1}, some, mask);
    size_t nonzero = 0;
    for (size_t p = 0; p < pixels; ++p)
        for (int c = 0; c < 3; ++c) {
            const double expected = mask[p] ? all.sum.channel(p, c) : 0.0;
            EXPECT_EQ(some.sum.channel(p, c), expected) << p;
            nonzero += expected != 0.0;
        }
    EXPECT_GT(nonzero, pixels / 4) << "a black image proves nothing";
    EXPECT_THROW(renderer.add({i, i + 1}, some), std::invalid_argument)
        << "a round after the first without its mask";
    EXPECT_THROW(renderer.add({i - 1, i + 1}, some, mask), std::invalid_argument)
        << "a range over two rounds";
}

// An algorithm that does not read the adaptive options (eyelight, a preview) refuses them,
// naming the algorithms that read them; every algorithm whose integrator takes masks reads them.
TEST(AdaptiveRender, RefusedByAlgorithmsThatDoNotReadIt) {
    try {
        resolve_render_settings("eyelight", {{"adaptive", "0.05"}}, SceneSettings{});
        FAIL() << "eyelight with adaptive sampling was accepted";
    } catch (const std::invalid_argument& e) {
        const std::string what = e.what();
        EXPECT_NE(what.find("not read by algorithm eyelight"), std::string::npos) << what;
        for (const char* reader :
             {"pt", "volpt", "lt", "bpt", "ppm", "bpm", "vcm", "upbp", "vpl", "ic"})
            EXPECT_NE(what.find(reader), std::string::npos) << reader << ": " << what;
    }
    for (const char* reader : {"lt", "bpt", "ppm", "bpm", "vcm", "upbp", "vpl", "ic"}) {
        const RenderSettings s =
            resolve_render_settings(reader, {{"adaptive", "0.05"}}, SceneSettings{});
        EXPECT_EQ(s.adaptive, 0.05) << reader;
    }
}

// The adaptive estimator against a converged uniform render (adaptive_renders.h): 48
// independent adaptive renders of the 12 x 12 Cornell box (threshold 0.3, 24 iterations) against
// 8192 uniform iterations.
TEST(AdaptiveRender, EstimatorMatchesAConvergedUniformRender) {
    auto scene = cornell_box(12);
    adaptive_test::expect_estimator_matches_reference(*scene, adaptive_settings(0, 0.3),
                                                      adaptive_settings(1000, 0), 8192, 48, 24);
}

// With every pixel active in every round (a threshold below any pixel's noise), an adaptive
// result's per-pixel counts all equal the global ones, and its error figures equal the uniform
// render's: estimate_relative_error's per-pixel-count sums (RelativeErrorSums::add_pixel) give
// the uniform figure for an even count, and for an odd one the uniform figure (which takes the
// halves as equal: half the difference) times the exact factor sqrt(4 n_o n_e) / n; the
// per-pixel errors are the same bit for bit.
TEST(AdaptiveRender, ErrorFiguresWithPerPixelCountsMatchTheUniformOnes) {
    auto scene = cornell_box(kSize);
    for (uint64_t iterations : {20, 21}) {
        SCOPED_TRACE(iterations);
        const IterationResult uniform =
            render_iterations(*scene, adaptive_settings(9, 0), 0, {1, iterations + 1});
        const IterationResult all_active =
            render_alone(*scene, adaptive_settings(9, 1e-300), iterations);
        for (uint64_t n : all_active.adaptive.count) ASSERT_EQ(n, iterations);
        const double a = estimate_relative_error(uniform), b = estimate_relative_error(all_active);
        const double n = double(iterations), n_odd = double((iterations + 1) / 2);
        const double factor = std::sqrt(4 * n_odd * (n - n_odd)) / n;
        std::printf(
            "%llu iterations: relative error uniform %.6g, adaptive with every pixel "
            "active %.6g (factor %.6g)\n",
            (unsigned long long)iterations, a, b, factor);
        EXPECT_GT(a, 0.0);
        EXPECT_NEAR(b, a * factor, 1e-12 * a);
        EXPECT_EQ(estimate_pixel_relative_errors(all_active),
                  estimate_pixel_relative_errors(uniform));
    }
}

// The per-pixel error estimate (--target-error per pixel) is calibrated: after kIterations
// uniform iterations of the Cornell box, each pixel's actual relative error of its brightness
// against a converged render (kReference iterations, whose own variance is 1/64 of the test's,
// left out) is compared with its estimate e_p (the 3 x 3 RMS of odd/even estimates). If e_p is the
// standard error of the pixel's relative brightness, the mean over pixels of (actual / e_p)^2 is
// 1; with 256 pixels, each ratio's variance about 2 + the nine-degree-of-freedom estimate's
// spread, and the windows' overlap, its standard error is about 0.15: the tolerance [0.5, 1.8]
// is more than 3 of them. A wrong estimate fails it: the per-iteration deviation instead of the
// mean's error (sqrt(n) = 8 times too large) gives 1/64, a missing factor of one half 1/4 or 4.
// And the largest estimate is an upper bound for every pixel's own (windowed) estimate.
TEST(AdaptiveRender, PerPixelRelativeErrorIsCalibrated) {
    auto scene = cornell_box(kSize);
    constexpr uint64_t kIterations = 64, kReference = 4096;
    const IterationResult test =
        render_iterations(*scene, adaptive_settings(11, 0), 0, {1, kIterations + 1});
    const IterationResult reference =
        render_iterations(*scene, adaptive_settings(1000, 0), 0, {1, kReference + 1});
    const std::vector<double> estimate = estimate_pixel_relative_errors(test);
    const size_t pixels = size_t(kSize) * kSize;
    ASSERT_EQ(estimate.size(), pixels);
    double ratio2 = 0;
    size_t used = 0;
    for (size_t p = 0; p < pixels; ++p) {
        double mean = 0, ref = 0;
        for (int c = 0; c < 3; ++c) {
            mean += test.sum.channel(p, c) / double(kIterations);
            ref += reference.sum.channel(p, c) / double(kReference);
        }
        if (!(estimate[p] > 0) || !std::isfinite(estimate[p])) continue;
        const double actual = (mean - ref) / std::max(ref, 1e-3);
        ratio2 += (actual / estimate[p]) * (actual / estimate[p]);
        ++used;
    }
    ASSERT_GT(used, pixels * 3 / 4);
    ratio2 /= double(used);
    const double largest = max_pixel_relative_error(test);
    std::printf(
        "per-pixel relative error: mean (actual / estimate)^2 %.3f over %zu pixels, "
        "largest estimate %.4f\n",
        ratio2, used, largest);
    EXPECT_GT(ratio2, 0.5);
    EXPECT_LT(ratio2, 1.8);
    for (double e : estimate) EXPECT_LE(e, largest);
    // Before any iteration the error is unknown.
    IterationRenderer renderer(*scene, adaptive_settings(11, 0), 0);
    EXPECT_TRUE(std::isinf(max_pixel_relative_error(renderer.empty_result())));
}

}  // namespace
}  // namespace render
