// Adaptive sampling's active-pixel mask (docs/reference/adaptive-sampling.md): exact sums, the
// mask's determinism under any split and merge order of the iterations, and its rules.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "core/image/fixed_point_sums.h"
#include "core/render/adaptive_mask.h"
#include "core/render/render_iterations.h"
#include "core/scene/loader/scene_loader.h"

namespace render {
namespace {

constexpr int kSize = 16;

std::unique_ptr<Scene> cornell_box(int size) {
    return load_scene(std::string(RENDER_SOURCE_DIR) + "/scenes/bitterli/cornell-box/scene_v3.xml",
                      {{"resx", std::to_string(size)}, {"resy", std::to_string(size)}});
}

// Iterations [first, end) in `order` of ranges: the ranges' sums (each summed in iteration
// order, as a worker does) merged in the order given, as the server merges reports.
struct Merged {
    FixedPointSums exact;
    std::vector<double> doubles;  // the image's double sums, for comparison
};

Merged merge_ranges(const std::vector<std::vector<double>>& images,
                    const std::vector<std::pair<uint64_t, uint64_t>>& ranges) {
    const size_t pixels = images[0].size() / 3;
    Merged out{FixedPointSums(pixels), std::vector<double>(images[0].size(), 0.0)};
    for (const auto& [first, end] : ranges) {
        FixedPointSums part(pixels);
        std::vector<double> part_doubles(images[0].size(), 0.0);
        for (uint64_t i = first; i < end; ++i) {
            part.add_iteration(images[i - 1], i);
            for (size_t k = 0; k < part_doubles.size(); ++k) part_doubles[k] += images[i - 1][k];
        }
        out.exact.add(part);
        for (size_t k = 0; k < part_doubles.size(); ++k) out.doubles[k] += part_doubles[k];
    }
    return out;
}

// The mask after 48 iterations of pt in the Cornell box (threshold: the median pixel's) is
// the same for one range, for three ranges merged in two orders and for 48 single iterations
// merged backwards: the exact sums
// are equal bit for bit, so the mask (a function of them) is too. The image's double sums of
// the same merges are printed: where they differ in their last bits, a mask taken from them
// could differ between worker counts.
TEST(AdaptiveMask, IsTheSameForAnySplitAndMergeOrder) {
    auto scene = cornell_box(kSize);
    RenderSettings settings;
    settings.algorithm = "pt";
    settings.seed = 4;
    constexpr uint64_t kIterations = 48;
    std::vector<std::vector<double>> images;
    for (uint64_t i = 1; i <= kIterations; ++i)
        images.push_back(render_iterations(*scene, settings, 0, {i, i + 1}).sum.values());
    std::vector<std::pair<uint64_t, uint64_t>> backwards;
    for (uint64_t i = kIterations; i >= 1; --i) backwards.push_back({i, i + 1});
    const std::vector<std::vector<std::pair<uint64_t, uint64_t>>> splits = {
        {{1, 49}}, {{1, 17}, {17, 30}, {30, 49}}, {{30, 49}, {1, 17}, {17, 30}}, backwards};
    const size_t pixels = size_t(kSize) * kSize;
    const std::vector<uint64_t> count(pixels, kIterations), odd(pixels, kIterations / 2);
    const Merged reference = merge_ranges(images, splits[0]);
    // The threshold is the median pixel's noise per iteration (deviation / (n * image mean)),
    // without window or spreading: half the pixels at the threshold's either side, so that many
    // decisions are close to it.
    std::vector<double> deviations;
    double image_mean = 0;
    for (size_t p = 0; p < pixels; ++p) {
        deviations.push_back(pixel_deviation(reference.exact.sum(p), reference.exact.odd_sum(p),
                                             kIterations, kIterations / 2));
        image_mean += FixedPointSums::to_value(reference.exact.sum(p)) / kIterations / pixels;
    }
    std::nth_element(deviations.begin(), deviations.begin() + pixels / 2, deviations.end());
    AdaptiveMaskSettings mask_settings;
    mask_settings.threshold = deviations[pixels / 2] / (double(kIterations) * image_mean);
    mask_settings.spread = 0;
    const std::vector<uint8_t> mask =
        adaptive_active_mask(reference.exact, kSize, kSize, count, odd, mask_settings);
    size_t active = 0;
    for (uint8_t a : mask) active += a;
    std::printf("active pixels at threshold %.4f: %zu of %zu\n", mask_settings.threshold, active,
                pixels);
    // A mask that is all on or all off would show no determinism at all.
    EXPECT_GT(active, pixels / 20);
    EXPECT_LT(active, pixels - pixels / 20);
    for (size_t s = 1; s < splits.size(); ++s) {
        SCOPED_TRACE(s);
        const Merged m = merge_ranges(images, splits[s]);
        size_t doubles_differ = 0;
        for (size_t k = 0; k < m.doubles.size(); ++k)
            doubles_differ += m.doubles[k] != reference.doubles[k];
        std::printf("split %zu: %zu of %zu double sums differ from one range's\n", s,
                    doubles_differ, m.doubles.size());
        for (size_t p = 0; p < pixels; ++p) {
            ASSERT_EQ(m.exact.sum(p), reference.exact.sum(p)) << p;
            ASSERT_EQ(m.exact.odd_sum(p), reference.exact.odd_sum(p)) << p;
        }
        EXPECT_EQ(adaptive_active_mask(m.exact, kSize, kSize, count, odd, mask_settings), mask);
    }
}

// Where double sums do depend on the merge order (values of a wide range with full double
// mantissas, as fireflies give: the Cornell box's 48 iterations above happen to sum exactly),
// the fixed-point sums do not: 64 pixels, 600 iterations of log-uniform values in
// [1e-3, 1e4), summed forwards and backwards.
TEST(AdaptiveMask, FixedPointSumsAreExactWhereDoubleSumsAreNot) {
    constexpr size_t kPixels = 64;
    constexpr uint64_t kIterations = 600;
    std::vector<std::vector<double>> images;
    uint64_t state = 12345;
    for (uint64_t i = 0; i < kIterations; ++i) {
        std::vector<double> rgb(3 * kPixels);
        for (double& v : rgb) {
            state = state * 6364136223846793005ull + 1442695040888963407ull;
            v = std::pow(10.0, -3.0 + 7.0 * double(state >> 11) / double(uint64_t(1) << 53)) / 3;
        }
        images.push_back(std::move(rgb));
    }
    std::vector<std::pair<uint64_t, uint64_t>> forwards, backwards;
    for (uint64_t i = 1; i <= kIterations; ++i) forwards.push_back({i, i + 1});
    backwards.assign(forwards.rbegin(), forwards.rend());
    const Merged a = merge_ranges(images, forwards), b = merge_ranges(images, backwards);
    size_t doubles_differ = 0;
    for (size_t k = 0; k < a.doubles.size(); ++k) doubles_differ += a.doubles[k] != b.doubles[k];
    std::printf("%zu of %zu double sums differ between the two orders\n", doubles_differ,
                a.doubles.size());
    EXPECT_GT(doubles_differ, 0u) << "the data does not show order dependence";
    for (size_t p = 0; p < kPixels; ++p) {
        EXPECT_EQ(a.exact.sum(p), b.exact.sum(p)) << p;
        EXPECT_EQ(a.exact.odd_sum(p), b.exact.odd_sum(p)) << p;
    }
}

TEST(AdaptiveMask, Rules) {
    // 3 x 3 frame, 4 iterations each, 2 odd. Pixel 0: odd and even means 1 and 1.1 (standard
    // error 0.05, deviation per iteration 0.05 * sqrt(4) = 0.1); the others: equal halves of 0.5
    // (deviation 0). Image mean: (1.05 + 8 * 0.5) / 9.
    FixedPointSums sums(9);
    for (uint64_t i = 1; i <= 4; ++i) {
        std::vector<double> rgb(27, 0.5 / 3);
        rgb[0] = rgb[1] = rgb[2] = (i % 2 ? 1.0 : 1.1) / 3;
        sums.add_iteration(rgb, i);
    }
    std::vector<uint64_t> count(9, 4), odd(9, 2);
    const auto value = [](int64_t exact) { return FixedPointSums::to_value(exact); };
    EXPECT_NEAR(halves_relative_error(value(sums.sum(0)), value(sums.odd_sum(0)), 4, 2, 1e-3),
                0.05 / 1.05, 1e-5);
    EXPECT_EQ(halves_relative_error(value(sums.sum(4)), value(sums.odd_sum(4)), 4, 2, 1e-3), 0.0);
    EXPECT_NEAR(pixel_deviation(sums.sum(0), sums.odd_sum(0), 4, 2), 0.1, 1e-5);
    EXPECT_EQ(pixel_deviation(sums.sum(4), sums.odd_sum(4), 4, 2), 0.0);
    const double image_mean = (1.05 + 8 * 0.5) / 9;
    // Pixel 0's noise per iteration: 0.1 / (4 * image mean); the others': dark / (4 * mean).
    const double noise0 = 0.1 / (4 * image_mean);
    AdaptiveMaskSettings s;
    s.threshold = noise0 * 0.99;
    s.spread = 0;
    std::vector<uint8_t> mask = adaptive_active_mask(sums, 3, 3, count, odd, s);
    EXPECT_EQ(mask, (std::vector<uint8_t>{1, 0, 0, 0, 0, 0, 0, 0, 0}));
    s.spread = 1;  // pixel 0's neighbours (1, 3, 4) join it
    mask = adaptive_active_mask(sums, 3, 3, count, odd, s);
    EXPECT_EQ(mask, (std::vector<uint8_t>{1, 1, 0, 1, 1, 0, 0, 0, 0}));
    s.threshold = noise0 * 1.01;  // above pixel 0's noise: nothing active
    mask = adaptive_active_mask(sums, 3, 3, count, odd, s);
    EXPECT_EQ(mask, std::vector<uint8_t>(9, 0));
    // The count is per pixel: with twice the iterations (and the same sums' halves scaled, so
    // the same deviation), pixel 0's noise per iteration halves.
    s.threshold = noise0 * 0.6;
    s.spread = 0;
    EXPECT_EQ(adaptive_active_mask(sums, 3, 3, count, odd, s)[0], 1);
    FixedPointSums doubled(9);
    doubled.add(sums);
    doubled.add(sums);  // as 8 iterations, 4 odd, with the same halves' means
    std::vector<uint64_t> count8(9, 8), odd8(9, 4);
    // The image mean is unchanged; the deviation grows by sqrt(2) (|m_o - m_e| sqrt(n) / 2),
    // the count by 2: noise0 * sqrt(2) / 2 = 0.71 noise0 > 0.6 noise0, still active; at
    // 0.75 noise0 it has stopped.
    EXPECT_EQ(adaptive_active_mask(doubled, 3, 3, count8, odd8, s)[0], 1);
    s.threshold = noise0 * 0.75;
    EXPECT_EQ(adaptive_active_mask(doubled, 3, 3, count8, odd8, s)[0], 0);
    // The 3 x 3 window: pixel 4 (the centre) sees pixel 0's deviation in its window's RMS,
    // 0.1 / 3; pixel 8 (the far corner) does not.
    s.error_window = 1;
    s.threshold = (0.1 / 3) / (4 * image_mean) * 0.99;
    mask = adaptive_active_mask(sums, 3, 3, count, odd, s);
    EXPECT_EQ(mask, (std::vector<uint8_t>{1, 1, 0, 1, 1, 0, 0, 0, 0}));
    s.error_window = 0;
    s.threshold = noise0 * 1.01;
    // A pixel without even iterations has an unknown error: active, and with the spread its
    // neighbours too.
    odd[8] = 4;
    s.spread = 1;
    mask = adaptive_active_mask(sums, 3, 3, count, odd, s);
    EXPECT_EQ(mask, (std::vector<uint8_t>{0, 0, 0, 0, 1, 1, 0, 1, 1}));
    // Consistency: a pixel whose halves agree exactly still takes iterations once the threshold
    // is below dark / (n * image mean).
    odd[8] = 2;
    s.spread = 0;
    s.threshold = s.dark / (4 * image_mean) * 0.99;
    EXPECT_EQ(adaptive_active_mask(sums, 3, 3, count, odd, s), std::vector<uint8_t>(9, 1));
    // NaN and huge values are quantized to the grid's range, never overflow.
    EXPECT_EQ(FixedPointSums::quantize(std::nan("")), 0);
    EXPECT_EQ(FixedPointSums::quantize(-1), 0);
    EXPECT_EQ(FixedPointSums::quantize(1e300), (int64_t(1) << 40) - 1);
    EXPECT_EQ(FixedPointSums::quantize(FixedPointSums::kMaxValue - 1e-9), (int64_t(1) << 40) - 1);
}

}  // namespace
}  // namespace render
