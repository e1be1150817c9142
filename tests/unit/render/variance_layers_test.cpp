// The per-pixel error layers (docs/reference/variance-layers.md): the variance of each pixel's
// mean from the sum of squares, checked by formula, on a constant scene, through the iteration
// contract, and by a per-pixel Z-test of two independent renders against each other.

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <limits>
#include <string>
#include <vector>

#include "core/image/variance_layers.h"
#include "core/render/render_iterations.h"
#include "core/scene/loader/scene_loader.h"

namespace render {
namespace {

std::unique_ptr<Scene> cornell_box(int size) {
    return load_scene(std::string(RENDER_SOURCE_DIR) + "/scenes/bitterli/cornell-box/scene_v3.xml",
                      {{"resx", std::to_string(size)}, {"resy", std::to_string(size)}});
}

// Camera inside a closed black sphere that emits `radiance`: every path tracer sample is that
// radiance exactly, so every iteration's pixel value is the same.
std::string constant_scene(const std::string& radiance) {
    return R"(<scene version="3.0.0">
  <sensor type="perspective">
    <float name="fov" value="70"/>
    <transform name="to_world"><lookat origin="0, 0, 0" target="0.3, 0.2, 1" up="0, 1, 0"/></transform>
    <film type="hdrfilm"><integer name="width" value="12"/><integer name="height" value="12"/></film>
  </sensor>
  <shape type="sphere">
    <float name="radius" value="1"/>
    <boolean name="flip_normals" value="true"/>
    <bsdf type="diffuse"><rgb name="reflectance" value="0"/></bsdf>
    <emitter type="area"><rgb name="radiance" value=")" +
           radiance + R"("/></emitter>
  </shape>
</scene>)";
}

const Image& layer(const std::vector<NamedLayer>& layers, const std::string& name) {
    for (const NamedLayer& l : layers)
        if (l.name == name) return l.image;
    throw std::runtime_error("no layer " + name);
}

IterationResult render_with_variance(const Scene& scene, uint64_t seed, IterationRange range) {
    RenderSettings settings;
    settings.algorithm = "pt";
    settings.seed = seed;
    settings.layers = LayerMode::Variance;
    return render_iterations(scene, settings, 0, range);
}

// Adds `part` (another range of the same frame) to `into`, as the server merges reports.
void merge(IterationResult& into, const IterationResult& part) {
    into.sum.add(part.sum);
    into.odd_sum.add(part.odd_sum);
    into.layers.add(part.layers);
    into.count += part.count;
    into.odd_count += part.odd_count;
}

TEST(VarianceOfMean, IsTheSampleVarianceOverTheCount) {
    // 1, 2, 3, 4: sample variance 5/3, of the mean 5/12.
    EXPECT_DOUBLE_EQ(variance_of_mean(10, 30, 4), 5.0 / 12.0);
    EXPECT_EQ(variance_of_mean(3, 9, 1), 0.0);  // one value: no spread to estimate
    EXPECT_EQ(variance_of_mean(0, 0, 0), 0.0);
}

TEST(VarianceOfMean, IsExactlyZeroForAConstantAndKeepsSmallRealSpread) {
    for (double v : {0.7, 1.0 / 3.0, 12345.678, 1e-20}) {
        double sum = 0, squares = 0;
        const uint64_t n = 100000;
        for (uint64_t i = 0; i < n; ++i) {
            sum += v;
            squares += v * v;
        }
        EXPECT_EQ(variance_of_mean(sum, squares, n), 0.0) << v;
    }
    // Relative spread 1e-4 (variance / mean^2 = 1e-8) is far above the rounding floor
    // (4 N eps = 9e-13 for N = 1000), and resolved to ~N eps / 1e-8 = 2e-5 of itself.
    double sum = 0, squares = 0;
    const uint64_t n = 1000;
    for (uint64_t i = 0; i < n; ++i) {
        const double v = 0.7 * (1 + (i % 2 ? 1e-4 : -1e-4));
        sum += v;
        squares += v * v;
    }
    const double expected = (0.7 * 1e-4) * (0.7 * 1e-4) * double(n) / double(n - 1) / double(n);
    EXPECT_NEAR(variance_of_mean(sum, squares, n), expected, 1e-3 * expected);
}

TEST(VarianceLayers, NoNanOrInfinityReachesTheLayers) {
    const double inf = std::numeric_limits<double>::infinity();
    const double nan = std::numeric_limits<double>::quiet_NaN();
    EXPECT_EQ(variance_of_mean(1, inf, 4), inf);
    EXPECT_EQ(finite_image_value(inf), std::numeric_limits<float>::max());
    EXPECT_EQ(finite_image_value(-inf), -std::numeric_limits<float>::max());
    EXPECT_EQ(finite_image_value(1e300), std::numeric_limits<float>::max());
    EXPECT_EQ(finite_image_value(nan), 0.0f);
    // Sums that no render produces (finite samples square to at most ~1e77), to show that even
    // they give finite layers.
    AccumulationBuffer sum(2, 2), odd(2, 2), squares(2, 2);
    const double values[][3] = {{1e200, 1e300, inf}, {nan, 1, 1}, {1, nan, 1}, {-1e300, 1e300, 1}};
    for (size_t p = 0; p < 4; ++p) {
        sum.add(p, Rgb{float(0), float(0), float(0)});
        sum.values()[3 * p] = values[p][0];
        odd.values()[3 * p + 1] = values[p][1];
        squares.values()[3 * p + 2] = values[p][2];
        squares.values()[3 * p] = values[p][1];
    }
    for (const NamedLayer& l : variance_layers(sum, odd, squares, 4, 2)) {
        for (size_t i = 0; i < l.image.pixel_count() * 3; ++i)
            EXPECT_TRUE(std::isfinite(l.image.data()[i])) << l.name << " value " << i;
    }
}

// A scene whose every sample is 0.7 (not a binary fraction: the sums round) has variance
// exactly 0, and both half images equal the image.
TEST(VarianceLayers, AConstantSceneHasZeroVariance) {
    auto scene = load_scene_from_string(constant_scene("0.7"), ".");
    const IterationResult r = render_with_variance(*scene, 3, IterationRange{1, 40});
    ASSERT_EQ(r.layers.size(), 1u);
    const std::vector<NamedLayer> layers = output_layers(r);
    ASSERT_EQ(layers.size(), 3u);
    const Image image = r.sum.average(double(r.count));
    for (size_t i = 0; i < image.pixel_count() * 3; ++i) {
        ASSERT_EQ(image.data()[i], 0.7f) << "the scene is not constant at value " << i;
        EXPECT_EQ(layer(layers, "variance").data()[i], 0.0f) << i;
        EXPECT_EQ(layer(layers, "odd_half").data()[i], 0.7f) << i;
        EXPECT_EQ(layer(layers, "even_half").data()[i], 0.7f) << i;
    }
}

// The iteration contract for the layers: ranges rendered apart and merged give the layers of
// the whole range (up to summation order, which the float layers do not show), and the half
// images average to the image.
TEST(VarianceLayers, SplitRangesGiveTheWholeRangesLayers) {
    auto scene = cornell_box(16);
    const IterationResult whole = render_with_variance(*scene, 7, IterationRange{1, 13});
    IterationResult parts = render_with_variance(*scene, 7, IterationRange{1, 6});
    merge(parts, render_with_variance(*scene, 7, IterationRange{6, 8}));
    merge(parts, render_with_variance(*scene, 7, IterationRange{8, 13}));
    const std::vector<NamedLayer> a = output_layers(whole), b = output_layers(parts);
    ASSERT_EQ(a.size(), 3u);
    ASSERT_EQ(b.size(), 3u);
    size_t differ = 0, nonzero = 0;
    for (size_t l = 0; l < 3; ++l) {
        ASSERT_EQ(a[l].name, b[l].name);
        for (size_t i = 0; i < a[l].image.pixel_count() * 3; ++i) {
            const float x = a[l].image.data()[i], y = b[l].image.data()[i];
            EXPECT_NEAR(x, y, 1e-6 * std::max(std::abs(x), std::abs(y))) << a[l].name << " " << i;
            differ += x != y;
            nonzero += x != 0;
        }
    }
    std::printf("split ranges: %zu of the layers' values differ in the last bits\n", differ);
    EXPECT_GT(nonzero, a[0].image.pixel_count() * 3);  // the layers are not black
    const Image image = whole.sum.average(double(whole.count));
    for (size_t i = 0; i < image.pixel_count() * 3; ++i) {
        const double halves =
            0.5 * (layer(a, "odd_half").data()[i] + layer(a, "even_half").data()[i]);
        EXPECT_NEAR(halves, image.data()[i], 1e-6 * (std::abs(halves) + 1e-30)) << i;
    }
}

// z of every pixel value: the difference of two independent renders' means over the square
// root of the sum of their variance layers.
std::vector<double> z_scores(const std::vector<NamedLayer>& a, const Image& image_a,
                             const std::vector<NamedLayer>& b, const Image& image_b,
                             double variance_factor, size_t* both_zero_mismatch) {
    std::vector<double> z;
    const Image& va = layer(a, "variance");
    const Image& vb = layer(b, "variance");
    for (size_t i = 0; i < image_a.pixel_count() * 3; ++i) {
        const double var = variance_factor * (double(va.data()[i]) + double(vb.data()[i]));
        const double diff = double(image_a.data()[i]) - double(image_b.data()[i]);
        if (var == 0) {
            // No spread seen in either render: the pixel is deterministic (black), so the
            // two means must agree exactly.
            *both_zero_mismatch += diff != 0;
            continue;
        }
        z.push_back(diff / std::sqrt(var));
    }
    return z;
}

// Fraction of |z| below `bound`.
double fraction_within(const std::vector<double>& z, double bound) {
    size_t in = 0;
    for (double v : z) in += std::abs(v) < bound;
    return double(in) / double(z.size());
}

// The per-pixel Z-test of two independent renders (seeds 1 and 2, 256 iterations each, pt in
// the Cornell box at 32 x 32). If the variance layer is the variance of each mean, every z is
// close to a standard normal (256 iterations: the means are close to normal, and the variance
// estimates have 255 degrees of freedom each). Two checks of the distribution:
//  - the fraction of |z| < 1 is P(|N(0,1)| < 1) = 0.6827, and of |z| < 2 is 0.9545. Each
//    fraction over M values has standard error sqrt(p (1 - p) / M); the three channels of a
//    pixel are correlated, so M is taken as the pixel count (1024), not the value count: a
//    conservative standard error (0.0145 and 0.0065). Tolerance k = 4 standard errors (a false
//    failure ~6e-5 per check; the seeds are fixed).
//  - Mitsuba's per-pixel test: the most extreme |z| over all M values must not reject at
//    significance 0.01 after the Sidak correction for M tests.
// A variance layer off by a factor 2 either way moves the first fraction to 0.843 or 0.520,
// 11 standard errors away: the test runs the same checks with the layers scaled by 2 and by
// 1/2 and requires both to fail.
TEST(VarianceLayers, PerPixelZTestOfTwoIndependentRenders) {
    auto scene = cornell_box(32);
    const IterationResult ra = render_with_variance(*scene, 1, IterationRange{1, 257});
    const IterationResult rb = render_with_variance(*scene, 2, IterationRange{1, 257});
    const std::vector<NamedLayer> la = output_layers(ra), lb = output_layers(rb);
    const Image ia = ra.sum.average(double(ra.count)), ib = rb.sum.average(double(rb.count));
    const double pixels = double(ia.pixel_count());
    struct Check {
        double bound, expected;
    };
    const Check checks[] = {{1.0, 0.6827}, {2.0, 0.9545}};
    auto passes = [&](double factor, bool print) {
        size_t mismatch = 0;
        const std::vector<double> z = z_scores(la, ia, lb, ib, factor, &mismatch);
        bool ok = mismatch == 0 && z.size() > size_t(pixels);
        for (const Check& c : checks) {
            const double f = fraction_within(z, c.bound);
            const double se = std::sqrt(c.expected * (1 - c.expected) / pixels);
            if (print)
                std::printf(
                    "variance x %.1f: |z| < %.0f for %.4f (normal %.4f, %.1f standard "
                    "errors)\n",
                    factor, c.bound, f, c.expected, (f - c.expected) / se);
            ok &= std::abs(f - c.expected) <= 4 * se;
        }
        double max_z = 0;
        for (double v : z) max_z = std::max(max_z, std::abs(v));
        // Sidak: per-value significance 1 - (1 - 0.01)^(1/M); two-sided normal tail.
        const double per_value = 1 - std::pow(1 - 0.01, 1.0 / double(z.size()));
        const double p_max = std::erfc(max_z / std::sqrt(2.0));
        if (print)
            std::printf(
                "variance x %.1f: max |z| %.2f, p %.3g (Sidak threshold %.3g), %zu "
                "values, %zu black mismatches\n",
                factor, max_z, p_max, per_value, z.size(), mismatch);
        ok &= p_max >= per_value;
        return ok;
    };
    EXPECT_TRUE(passes(1.0, true)) << "the variance layer does not match the renders' spread";
    EXPECT_FALSE(passes(2.0, true)) << "a variance twice too large passes the Z-test";
    EXPECT_FALSE(passes(0.5, true)) << "a variance half too small passes the Z-test";
}

}  // namespace
}  // namespace render
