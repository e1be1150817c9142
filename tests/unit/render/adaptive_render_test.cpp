// Adaptive sampling wired into the renderer (docs/reference/adaptive-sampling.md): the same
// sums for any split of the rounds over "workers", per-pixel counts, the pixel loop's mask, and
// the adaptive estimator against a converged uniform render.

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "core/render/adaptive_rounds.h"
#include "core/render/render_iterations.h"
#include "core/scene/loader/scene_loader.h"

namespace render {
namespace {

constexpr int kSize = 16;

std::unique_ptr<Scene> cornell_box(int size) {
    return load_scene(std::string(RENDER_SOURCE_DIR) + "/scenes/bitterli/cornell-box/scene_v3.xml",
                      {{"resx", std::to_string(size)}, {"resy", std::to_string(size)}});
}

RenderSettings adaptive_settings(uint64_t seed, double threshold) {
    RenderSettings settings;
    settings.algorithm = "pt";
    settings.seed = seed;
    settings.threads = 2;
    settings.adaptive = threshold;
    settings.adaptive_min_iterations = 8;
    settings.adaptive_round = 4;
    return settings;
}

// What the server does with reports: sums added, counts added (exact for the integer parts).
void merge(IterationResult& into, const IterationResult& from) {
    into.sum.add(from.sum);
    into.odd_sum.add(from.odd_sum);
    into.count += from.count;
    into.odd_count += from.odd_count;
    into.adaptive.add(from.adaptive);
    into.stats += from.stats;
}

// One process, one iteration per call (as `render`).
IterationResult render_alone(const Scene& scene, const RenderSettings& settings,
                             uint64_t iterations) {
    IterationRenderer renderer(scene, settings, 0);
    IterationResult result = renderer.empty_result();
    for (uint64_t i = 1; i <= iterations; ++i) renderer.add_adaptive({i, i + 1}, result);
    return result;
}

// A "farm": each round's iterations split into `workers` ranges, each rendered by its own
// renderer into its own result from the round's mask, and merged in reverse order; the mask of
// the next round is computed from the merged sums at the boundary, as the server would.
IterationResult render_farm(const Scene& scene, const RenderSettings& settings, uint64_t iterations,
                            int workers, std::vector<std::vector<uint8_t>>& masks) {
    const AdaptiveRounds rounds(settings);
    const int width = scene.camera().width(), height = scene.camera().height();
    IterationRenderer probe(scene, settings, 0);
    IterationResult merged = probe.empty_result();
    for (uint64_t round = 0; rounds.first(round) <= iterations; ++round) {
        const uint64_t first = rounds.first(round);
        const uint64_t end = std::min(rounds.end(round), iterations + 1);
        std::vector<uint8_t> mask;
        if (round > 0) mask = adaptive_round_mask(merged.adaptive, width, height, settings);
        masks.push_back(mask);
        std::vector<IterationResult> parts;
        const uint64_t n = end - first;
        for (int w = 0; w < workers; ++w) {
            const uint64_t a = first + n * uint64_t(w) / uint64_t(workers);
            const uint64_t b = first + n * uint64_t(w + 1) / uint64_t(workers);
            if (a == b) continue;
            IterationRenderer renderer(scene, settings, 0);
            IterationResult part = renderer.empty_result();
            renderer.add({a, b}, part, mask);
            parts.push_back(std::move(part));
        }
        for (auto it = parts.rbegin(); it != parts.rend(); ++it) merge(merged, *it);
    }
    return merged;
}

// The exact sums and the per-pixel counts are bit for bit the same whether one process renders
// the job iteration by iteration or 1, 2 or 3 "workers" split every round and their results
// are merged in reverse order; the images agree to summation order. The threshold leaves a
// part of the pixels active, so the masks matter.
void expect_same_for_any_split(const Scene& scene, const RenderSettings& settings) {
    constexpr uint64_t kIterations = 32;
    const IterationResult alone = render_alone(scene, settings, kIterations);
    uint64_t total = 0;
    for (uint64_t n : alone.adaptive.count) total += n;
    const uint64_t pixels = uint64_t(scene.camera().width()) * scene.camera().height();
    // Not every pixel took every iteration, and not only the first 8 (the test needs both).
    EXPECT_LT(total, pixels * kIterations);
    EXPECT_GT(total, pixels * 8 + 4);
    for (int workers : {1, 2, 3}) {
        std::vector<std::vector<uint8_t>> masks;
        const IterationResult farm = render_farm(scene, settings, kIterations, workers, masks);
        ASSERT_EQ(farm.count, kIterations);
        EXPECT_EQ(farm.adaptive.count, alone.adaptive.count) << workers << " workers";
        EXPECT_EQ(farm.adaptive.odd_count, alone.adaptive.odd_count) << workers << " workers";
        for (size_t p = 0; p < pixels; ++p) {
            ASSERT_EQ(farm.adaptive.exact.sum(p), alone.adaptive.exact.sum(p)) << p;
            ASSERT_EQ(farm.adaptive.exact.odd_sum(p), alone.adaptive.exact.odd_sum(p)) << p;
        }
        const Image a = mean_image(alone), b = mean_image(farm);
        for (size_t p = 0; p < pixels; ++p)
            for (int c = 0; c < 3; ++c) {
                const float x = a.data()[3 * p + c], y = b.data()[3 * p + c];
                ASSERT_NEAR(x, y, 1e-6 * std::max(1.0f, std::abs(x))) << p;
            }
        EXPECT_EQ(farm.stats.samples, total) << "one sample per active pixel and iteration";
    }
}

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

// Unsupported combinations are refused with a message naming what is supported.
TEST(AdaptiveRender, RefusesAlgorithmsWithoutAPixelLoop) {
    auto scene = cornell_box(kSize);
    RenderSettings settings = adaptive_settings(1, 0.05);
    settings.algorithm = "bpt";
    try {
        IterationRenderer renderer(*scene, settings, 0);
        FAIL() << "bpt with adaptive sampling was accepted";
    } catch (const std::invalid_argument& e) {
        EXPECT_NE(std::string(e.what()).find("pt and volpt"), std::string::npos) << e.what();
    }
}

// The adaptive estimator against a converged uniform render. The mask of a round depends on
// earlier iterations only and each iteration is an unbiased estimate of the pixel, so each
// round's contribution is unbiased given the past; the pixel's mean divides by a count that
// depends on the past (a stopping rule), which leaves a bias that vanishes as the counts grow
// (docs/reference/adaptive-sampling.md, "What the mask does to the estimator"). The test averages
// kSeeds independent adaptive renders and compares each pixel and channel with the reference:
// z = (mean over seeds - reference) / (standard error of that difference). The mean of z over
// the image must lie within 4 / sqrt(pixels) of 0 and the mean of z^2 within 1 +- 4 sqrt(2 /
// pixels): 4 standard errors of those means for independent pixels, counting the three channels
// of a pixel as one (they are correlated), so a bias must stay below the resolution of kSeeds
// renders. The test's power: the wrong estimator that divides every pixel by the global
// iteration count (inactive pixels darkened) is computed from the same renders and must fail.
TEST(AdaptiveRender, EstimatorMatchesAConvergedUniformRender) {
    constexpr int kRes = 12;
    auto scene = cornell_box(kRes);
    const size_t pixels = size_t(kRes) * kRes;
    // The reference: kReference uniform iterations, each pixel's variance from its sum of squares.
    constexpr uint64_t kReference = 8192;
    RenderSettings uniform = adaptive_settings(1000, 0);
    uniform.layers = LayerMode::Variance;
    const IterationResult reference = render_iterations(*scene, uniform, 0, {1, kReference + 1});
    const std::vector<double>& squares = reference.layers.buffer(0).values();
    constexpr int kSeeds = 48;
    constexpr uint64_t kIterations = 24;
    const size_t values = 3 * pixels;
    std::vector<double> mean(values, 0.0), mean2(values, 0.0), wrong(values, 0.0);
    uint64_t samples = 0;
    for (int seed = 0; seed < kSeeds; ++seed) {
        const IterationResult r =
            render_alone(*scene, adaptive_settings(uint64_t(seed) + 1, 0.3), kIterations);
        const Image image = mean_image(r);
        for (size_t k = 0; k < values; ++k) {
            const double v = image.data()[k];
            mean[k] += v / kSeeds;
            mean2[k] += v * v / kSeeds;
            wrong[k] += r.sum.values()[k] / double(r.count) / kSeeds;
        }
        for (uint64_t n : r.adaptive.count) samples += n;
    }
    ASSERT_LT(samples, uint64_t(kSeeds) * pixels * kIterations * 9 / 10)
        << "the threshold must leave pixels inactive for the test to test adaptive sampling";
    struct Z {
        double sum = 0, sum2 = 0;
    } z, z_wrong;
    size_t used = 0;
    const double n = double(kReference);
    for (size_t k = 0; k < values; ++k) {
        const double ref_mean = reference.sum.values()[k] / n;
        const double ref_var = std::max(0.0, squares[k] / n - ref_mean * ref_mean) / (n - 1);
        const double seeds_var = std::max(0.0, mean2[k] - mean[k] * mean[k]) / (kSeeds - 1);
        const double se = std::sqrt(seeds_var + ref_var);
        if (!(se > 0)) continue;
        const double a = (mean[k] - ref_mean) / se, b = (wrong[k] - ref_mean) / se;
        z.sum += a;
        z.sum2 += a * a;
        z_wrong.sum += b;
        z_wrong.sum2 += b * b;
        ++used;
    }
    ASSERT_GT(used, values * 3 / 4);
    const double z_mean = z.sum / double(used), z2_mean = z.sum2 / double(used);
    const double mean_tolerance = 4.0 / std::sqrt(double(pixels));
    const double z2_tolerance = 4.0 * std::sqrt(2.0 / double(pixels));
    std::printf(
        "adaptive estimator vs uniform reference: %zu values, mean z %.3f (tolerance "
        "%.3f), mean z^2 %.3f (1 +- %.3f); wrong estimator: mean z %.3f, mean z^2 %.3f; "
        "%.1f %% of the uniform samples\n",
        used, z_mean, mean_tolerance, z2_mean, z2_tolerance, z_wrong.sum / double(used),
        z_wrong.sum2 / double(used),
        100.0 * double(samples) / double(uint64_t(kSeeds) * pixels * kIterations));
    EXPECT_LT(std::abs(z_mean), mean_tolerance);
    EXPECT_LT(std::abs(z2_mean - 1.0), z2_tolerance);
    EXPECT_TRUE(std::abs(z_wrong.sum / double(used)) >= mean_tolerance ||
                std::abs(z_wrong.sum2 / double(used) - 1.0) >= z2_tolerance)
        << "the test cannot tell the wrong estimator from the right one";
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
