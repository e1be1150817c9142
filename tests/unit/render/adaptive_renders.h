#pragma once

// What the adaptive-sampling tests share (docs/reference/adaptive-sampling.md): a Cornell box,
// adaptive settings, a render iteration by iteration as `render` does it, a "farm" that splits
// every round over workers and merges as the server does, and the comparison of many adaptive
// renders with a converged uniform one.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "core/render/adaptive_rounds.h"
#include "core/render/render_iterations.h"
#include "core/scene/loader/scene_loader.h"

namespace render::adaptive_test {

inline std::unique_ptr<Scene> cornell_box(int size) {
    return load_scene(std::string(RENDER_SOURCE_DIR) + "/scenes/bitterli/cornell-box/scene_v3.xml",
                      {{"resx", std::to_string(size)}, {"resy", std::to_string(size)}});
}

inline RenderSettings adaptive_settings(uint64_t seed, double threshold,
                                        const std::string& algorithm = "pt") {
    RenderSettings settings;
    settings.algorithm = algorithm;
    settings.seed = seed;
    settings.threads = 2;
    settings.adaptive = threshold;
    settings.adaptive_min_iterations = 8;
    settings.adaptive_round = 4;
    return settings;
}

// What the server does with reports: sums added, counts added (exact for the integer parts).
inline void merge(IterationResult& into, const IterationResult& from) {
    into.sum.add(from.sum);
    into.odd_sum.add(from.odd_sum);
    into.count += from.count;
    into.odd_count += from.odd_count;
    into.adaptive.add(from.adaptive);
    into.stats += from.stats;
}

// One process, one iteration per call (as `render`).
inline IterationResult render_alone(const Scene& scene, const RenderSettings& settings,
                                    uint64_t iterations) {
    IterationRenderer renderer(scene, settings, 0);
    IterationResult result = renderer.empty_result();
    for (uint64_t i = 1; i <= iterations; ++i) renderer.add_adaptive({i, i + 1}, result);
    return result;
}

// A "farm": each round's iterations split into `workers` ranges, each rendered by its own
// renderer into its own result from the round's mask, and merged in reverse order; the mask of
// the next round is computed from the merged sums at the boundary, as the server would.
inline IterationResult render_farm(const Scene& scene, const RenderSettings& settings,
                                   uint64_t iterations, int workers,
                                   std::vector<std::vector<uint8_t>>& masks) {
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
inline void expect_same_for_any_split(const Scene& scene, const RenderSettings& settings) {
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

// The adaptive estimator against a converged uniform render. The mask of a round depends on
// earlier iterations only and each iteration is an unbiased estimate of the pixel (for a
// merging algorithm: of the pixel blurred by that iteration's kernel), so each round's
// contribution is unbiased given the past; the pixel's mean divides by a count that depends on
// the past (a stopping rule), which leaves a bias that vanishes as the counts grow
// (docs/reference/adaptive-sampling.md, "What the mask does to the estimator"). The comparison
// averages `seeds` independent adaptive renders (settings `adaptive` with seeds 1, 2, ...) and
// compares each pixel and channel with `uniform` rendered for `reference_iterations` (its
// variance from the variance layer's sum of squares): z = (mean over seeds - reference) /
// (standard error of that difference). The mean of z over the image must lie within 4 /
// sqrt(pixels) of 0 and the mean of z^2 within 1 +- 4 sqrt(2 / pixels): 4 standard errors of
// those means for independent pixels, counting the three channels of a pixel as one (they are
// correlated), so a bias must stay below the resolution of `seeds` renders. The test's power:
// the wrong estimator that divides every pixel by the global iteration count (inactive pixels
// darkened) is computed from the same renders and must fail.
inline void expect_estimator_matches_reference(const Scene& scene, RenderSettings adaptive,
                                               RenderSettings uniform,
                                               uint64_t reference_iterations, int seeds,
                                               uint64_t iterations) {
    const size_t pixels = size_t(scene.camera().width()) * scene.camera().height();
    uniform.adaptive = 0;
    uniform.layers = LayerMode::Variance;
    const IterationResult reference =
        render_iterations(scene, uniform, 0, {1, reference_iterations + 1});
    const std::vector<double>& squares = reference.layers.buffer(0).values();
    const size_t values = 3 * pixels;
    std::vector<double> mean(values, 0.0), mean2(values, 0.0), wrong(values, 0.0);
    uint64_t samples = 0;
    for (int seed = 0; seed < seeds; ++seed) {
        adaptive.seed = uint64_t(seed) + 1;
        const IterationResult r = render_alone(scene, adaptive, iterations);
        const Image image = mean_image(r);
        for (size_t k = 0; k < values; ++k) {
            const double v = image.data()[k];
            mean[k] += v / seeds;
            mean2[k] += v * v / seeds;
            wrong[k] += r.sum.values()[k] / double(r.count) / seeds;
        }
        for (uint64_t n : r.adaptive.count) samples += n;
    }
    ASSERT_LT(samples, uint64_t(seeds) * pixels * iterations * 9 / 10)
        << "the threshold must leave pixels inactive for the test to test adaptive sampling";
    struct Z {
        double sum = 0, sum2 = 0;
    } z, z_wrong;
    size_t used = 0;
    const double n = double(reference_iterations);
    for (size_t k = 0; k < values; ++k) {
        const double ref_mean = reference.sum.values()[k] / n;
        const double ref_var = std::max(0.0, squares[k] / n - ref_mean * ref_mean) / (n - 1);
        const double seeds_var = std::max(0.0, mean2[k] - mean[k] * mean[k]) / (seeds - 1);
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
        "%s: adaptive estimator vs uniform reference: %zu values, mean z %.3f (tolerance "
        "%.3f), mean z^2 %.3f (1 +- %.3f); wrong estimator: mean z %.3f, mean z^2 %.3f; "
        "%.1f %% of the uniform samples\n",
        adaptive.algorithm.c_str(), used, z_mean, mean_tolerance, z2_mean, z2_tolerance,
        z_wrong.sum / double(used), z_wrong.sum2 / double(used),
        100.0 * double(samples) / double(uint64_t(seeds) * pixels * iterations));
    EXPECT_LT(std::abs(z_mean), mean_tolerance);
    EXPECT_LT(std::abs(z2_mean - 1.0), z2_tolerance);
    EXPECT_TRUE(std::abs(z_wrong.sum / double(used)) >= mean_tolerance ||
                std::abs(z_wrong.sum2 / double(used) - 1.0) >= z2_tolerance)
        << "the test cannot tell the wrong estimator from the right one";
}

}  // namespace render::adaptive_test
