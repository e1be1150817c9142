// The dashboard's per-pixel maps (core/render/adaptive_maps.h): the variance from the variance
// layer or the odd/even halves, each pixel's sample count, and the false-colour images.

#include "core/render/adaptive_maps.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>

#include "core/image/variance_layers.h"
#include "tests/unit/render/adaptive_renders.h"

namespace render {
namespace {

using adaptive_test::adaptive_settings;
using adaptive_test::cornell_box;

// A 2 x 1 frame with hand-made sums: pixel 0 grey values 1, 3 over iterations 1, 2 (odd 1);
// pixel 1 values 2, 2.
IterationResult two_pixels(LayerMode layers) {
    IterationResult r;
    r.sum = AccumulationBuffer(2, 1);
    r.odd_sum = AccumulationBuffer(2, 1);
    r.layers = TechniqueLayers(layers, 2, 1);
    r.sum.add(0, Rgb(4.0f));
    r.odd_sum.add(0, Rgb(1.0f));
    r.sum.add(1, Rgb(4.0f));
    r.odd_sum.add(1, Rgb(2.0f));
    if (layers == LayerMode::Variance) {
        r.layers.buffer(0).add(0, Rgb(10.0f));  // 1 + 9
        r.layers.buffer(0).add(1, Rgb(8.0f));   // 4 + 4
    }
    r.count = 2;
    r.odd_count = 1;
    return r;
}

TEST(PixelMaps, HalvesAndVarianceLayer) {
    // Halves: (m_o - m_e)^2 n_o n_e / n^2 = 4 / 4 = 1 for pixel 0, 0 for pixel 1; the 3 x 3
    // window (here both pixels) averages them: 0.5 each.
    const PixelMaps halves = pixel_maps(two_pixels(LayerMode::None));
    EXPECT_EQ(halves.variance_source, "odd/even halves");
    ASSERT_EQ(halves.variance.size(), 2u);
    EXPECT_DOUBLE_EQ(halves.variance[0], 0.5);
    EXPECT_DOUBLE_EQ(halves.variance[1], 0.5);
    EXPECT_EQ(halves.samples, (std::vector<double>{2, 2}));
    // The variance layer: the sample variance of 1, 3 is 2, of the mean 1; of 2, 2 zero.
    const PixelMaps layer = pixel_maps(two_pixels(LayerMode::Variance));
    EXPECT_EQ(layer.variance_source, "variance layer");
    EXPECT_DOUBLE_EQ(layer.variance[0], variance_of_mean(4, 10, 2));
    EXPECT_DOUBLE_EQ(layer.variance[0], 1.0);
    EXPECT_DOUBLE_EQ(layer.variance[1], 0.0);
    // One iteration: a half is empty, the variance unknown.
    IterationResult one = two_pixels(LayerMode::None);
    one.count = 1;
    const PixelMaps unknown = pixel_maps(one);
    EXPECT_TRUE(std::isnan(unknown.variance[0]));
    // Nothing merged: counts of 0, no variance.
    IterationResult none;
    none.sum = AccumulationBuffer(2, 1);
    none.odd_sum = AccumulationBuffer(2, 1);
    EXPECT_TRUE(pixel_maps(none).variance.empty());
    EXPECT_EQ(pixel_maps(none).samples, (std::vector<double>{0, 0}));
}

// An adaptive result: each pixel's own counts.
TEST(PixelMaps, AdaptiveCountsArePerPixel) {
    auto scene = cornell_box(16);
    const IterationResult r = adaptive_test::render_alone(*scene, adaptive_settings(3, 0.3), 32);
    const PixelMaps maps = pixel_maps(r);
    ASSERT_EQ(maps.samples.size(), r.adaptive.count.size());
    double least = 1e300, most = 0;
    for (size_t p = 0; p < maps.samples.size(); ++p) {
        EXPECT_EQ(maps.samples[p], double(r.adaptive.count[p]));
        least = std::min(least, maps.samples[p]);
        most = std::max(most, maps.samples[p]);
    }
    EXPECT_LT(least, most) << "the mask must have stopped some pixels";
}

// The halves' estimate is unbiased for the variance of the mean. 16 x 16 pixels of 64 Gaussian
// values each (fixed seed), every pixel with its own mean and one standard deviation (so that
// the 3 x 3 window, whose members all estimate the same variance, keeps the expectation): the
// sum over the pixels of the halves' estimate against the sum of the variance layer's (the
// unbiased sample variance, 63 degrees of freedom per pixel). Each pixel's halves estimate is
// sigma^2 / n times a chi-square of one degree of freedom, so the ratio of the sums has a
// standard error of about sqrt(2 / 256) = 0.09 (the window's averaging lowers it): [0.65, 1.35]
// is 4 of them. A factor of 2 in the estimate (the halves' difference without the n_o n_e / n^2
// factor gives 4) fails it. (On a rendered scene the sums can differ far more: a pixel whose
// noise is a few rare bright paths has a halves estimate of very few degrees of freedom; on the
// 16 x 16 Cornell box after 64 iterations their sums differed 2.6 times, from the pixels at the
// light's edge. The map shows the variance layer's where the job has it.)
TEST(PixelMaps, HalvesMatchTheVarianceLayerOnAverage) {
    constexpr int kSize = 16;
    constexpr uint64_t kIterations = 64;
    const size_t pixels = size_t(kSize) * kSize;
    IterationResult r;
    r.sum = AccumulationBuffer(kSize, kSize);
    r.odd_sum = AccumulationBuffer(kSize, kSize);
    r.layers = TechniqueLayers(LayerMode::Variance, kSize, kSize);
    std::mt19937_64 random(12345);
    std::normal_distribution<double> noise(0.0, 0.5);
    for (uint64_t i = 1; i <= kIterations; ++i)
        for (size_t p = 0; p < pixels; ++p) {
            const float value = float(1.0 + 0.01 * double(p) + noise(random));
            r.sum.add(p, Rgb(value));
            if (i % 2 == 1) r.odd_sum.add(p, Rgb(value));
            r.layers.buffer(0).add(p, Rgb(value * value));
        }
    r.count = kIterations;
    r.odd_count = kIterations / 2;
    IterationResult without = r;
    without.layers = TechniqueLayers(LayerMode::None, kSize, kSize);
    const PixelMaps a = pixel_maps(r), b = pixel_maps(without);
    double sum_a = 0, sum_b = 0;
    for (size_t p = 0; p < pixels; ++p) {
        sum_a += a.variance[p];
        sum_b += b.variance[p];
    }
    ASSERT_GT(sum_a, 0);
    const double ratio = sum_b / sum_a;
    std::printf(
        "sum of the halves' variance over the variance layer's: %.3f; the layer's mean "
        "over sigma^2 / n: %.3f\n",
        ratio, sum_a / double(pixels) / (0.25 / double(kIterations)));
    EXPECT_GT(ratio, 0.65);
    EXPECT_LT(ratio, 1.35);
}

TEST(HeatMap, RampScalesAndUnknownValues) {
    // Linear: least and largest value at the ramp's ends, NaN grey.
    const std::vector<double> counts = {8, 16, 24, std::nan("")};
    const HeatMap linear = heat_map(counts, 2, 2, false);
    EXPECT_EQ(linear.low, 8);
    EXPECT_EQ(linear.high, 24);
    EXPECT_FALSE(linear.log_scale);
    const Rgb lo = linear.image.at(size_t(0)), mid = linear.image.at(size_t(1)),
              hi = linear.image.at(size_t(2)), grey = linear.image.at(size_t(3));
    // Dark blue at the low end, light yellow at the high end, brighter in between.
    EXPECT_LT(lo.r + lo.g + lo.b, mid.r + mid.g + mid.b);
    EXPECT_LT(mid.r + mid.g + mid.b, hi.r + hi.g + hi.b);
    EXPECT_GT(lo.b, lo.r);
    EXPECT_GT(hi.r, hi.b);
    EXPECT_EQ(grey.r, grey.g);
    EXPECT_EQ(grey.g, grey.b);
    // One value everywhere: the ramp's middle.
    const HeatMap flat = heat_map(std::vector<double>{16, 16}, 2, 1, false);
    EXPECT_EQ(flat.low, 16);
    EXPECT_EQ(flat.high, 16);
    EXPECT_EQ(flat.image.at(size_t(0)).r, flat.image.at(size_t(1)).r);
    // Log: the 1st and 99th percentiles of the positive values, so one firefly among 200
    // values does not set the top; values <= 0 at the low end.
    std::vector<double> v(200);
    for (size_t i = 0; i < v.size(); ++i) v[i] = std::pow(10.0, -4.0 + 2.0 * double(i) / 199);
    v[199] = 1e6;  // a firefly
    v[0] = 0;
    const HeatMap log = heat_map(v, 200, 1, true);
    EXPECT_TRUE(log.log_scale);
    EXPECT_NEAR(std::log10(log.high), -4.0 + 2.0 * 198 / 199, 1e-9);
    EXPECT_NEAR(std::log10(log.low), -4.0 + 2.0 * 2 / 199, 1e-9);
    EXPECT_EQ(log.image.at(size_t(0)).r, log.image.at(size_t(1)).r);      // 0: the low end
    EXPECT_EQ(log.image.at(size_t(199)).r, log.image.at(size_t(198)).r);  // clipped at high
    EXPECT_THROW(heat_map(v, 3, 3, true), std::invalid_argument);
}

TEST(PixelMaps, FromTheLayersOfAFinishedFrame) {
    Image image(2, 1), variance(2, 1), samples(2, 1);
    variance.set(0, Rgb(0.5f, 1.0f, 1.5f));
    samples.set(0, Rgb(8.0f));
    samples.set(1, Rgb(20.0f));
    const PixelMaps both = pixel_maps_from_exr(image, &variance, &samples, {});
    EXPECT_EQ(both.variance_source, "variance layer");
    EXPECT_DOUBLE_EQ(both.variance[0], 1.0);
    EXPECT_EQ(both.samples, (std::vector<double>{8, 20}));
    // Neither layer: the iteration count for every pixel, no variance.
    const PixelMaps plain =
        pixel_maps_from_exr(image, nullptr, nullptr, {{"render:iterations", "64"}});
    EXPECT_TRUE(plain.variance.empty());
    EXPECT_EQ(plain.samples, (std::vector<double>{64, 64}));
    Image small(1, 1);
    EXPECT_THROW(pixel_maps_from_exr(image, &small, nullptr, {}), std::invalid_argument);
}

}  // namespace
}  // namespace render
