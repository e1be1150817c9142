// Distribution1D (discrete and continuous) and Distribution2D: exact probabilities, edge cases
// (zero weights, all-zero weights, a single bin, u at 0 and just below 1) and chi-square tests.

#include "core/sampling/distribution.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <optional>
#include <string>
#include <vector>

#include "core/math/constants.h"
#include "tests/support/chi_square.h"

namespace render::testing {
namespace {

// The chi-square checks of this file, Sidak-corrected together (tests/support/chi_square.h).
// The densities here are piecewise constant with jumps on cell edges, so every check compares
// against exact cell probabilities (chi_square_test_discrete) rather than integrated cells.
ChiSquareFamily family;

constexpr int kSamples = 1000000;

const std::vector<float> kWeights = {1.0f, 0.0f, 3.0f, 2.0f, 0.0f, 0.5f, 0.0f};

TEST(Distribution1D, DiscreteProbabilitiesAreNormalisedWeights) {
    Distribution1D d(kWeights);
    ASSERT_EQ(d.size(), kWeights.size());
    float sum = std::accumulate(kWeights.begin(), kWeights.end(), 0.0f);
    EXPECT_FLOAT_EQ(d.integral(), sum / float(kWeights.size()));
    double total = 0;
    for (size_t i = 0; i < kWeights.size(); ++i) {
        EXPECT_FLOAT_EQ(d.discrete_probability(i), kWeights[i] / sum) << i;
        total += d.discrete_probability(i);
    }
    EXPECT_NEAR(total, 1.0, 1e-6);
    EXPECT_EQ(d.discrete_probability(kWeights.size()), 0.0f);  // out of range
}

TEST(Distribution1D, DiscreteNeverPicksAZeroWeight) {
    Distribution1D d(kWeights);
    std::vector<float> us = {0.0f, kOneMinusEpsilon};
    for (int i = 0; i <= 1000; ++i) us.push_back(float(i) / 1000.0f * kOneMinusEpsilon);
    // Exactly on the cdf's steps, where ties between bins are decided.
    for (float c : {1.0f / 6.5f, 4.0f / 6.5f, 6.0f / 6.5f}) us.push_back(c);
    for (float u : us) {
        float probability, remapped;
        size_t i = d.sample_discrete(u, &probability, &remapped);
        ASSERT_LT(i, kWeights.size());
        EXPECT_GT(kWeights[i], 0.0f) << "u = " << u;
        EXPECT_FLOAT_EQ(probability, d.discrete_probability(i));
        EXPECT_GE(remapped, 0.0f);
        EXPECT_LT(remapped, 1.0f);
    }
}

CHI_SQUARE_TEST(family, Distribution1D, DiscreteChiSquare, 1) {
    Distribution1D d(kWeights);
    const size_t n = kWeights.size();
    std::vector<double> observed(n, 0.0), probability(n);
    Rng rng(StreamKey{1, 0, 1, 0});
    for (int i = 0; i < kSamples; ++i) observed[d.sample_discrete(rng.next_1d())] += 1;
    double sum = std::accumulate(kWeights.begin(), kWeights.end(), 0.0);
    for (size_t i = 0; i < n; ++i) probability[i] = kWeights[i] / sum;  // from the weights
    ChiSquareResult r = chi_square_test_discrete(family, observed, probability, kSamples);
    EXPECT_TRUE(r.passed) << r.message;
}

CHI_SQUARE_TEST(family, Distribution1D, ContinuousChiSquareAndPdf, 1) {
    Distribution1D d(kWeights);
    const int n = int(kWeights.size()), cells_per_bin = 4, cells = n * cells_per_bin;
    std::vector<double> observed(cells, 0.0), probability(cells);
    Rng rng(StreamKey{2, 0, 1, 0});
    for (int i = 0; i < kSamples; ++i) {
        float pdf;
        size_t index;
        float x = d.sample_continuous(rng.next_1d(), &pdf, &index);
        ASSERT_TRUE(x >= 0 && x < 1) << x;
        // The reported pdf and bin are those of the returned point.
        ASSERT_EQ(pdf, d.pdf_continuous(x));
        ASSERT_EQ(index, size_t(x * n));
        observed[std::min(int(x * cells), cells - 1)] += 1;
    }
    // 4 cells per bin: also checks uniformity inside a bin. Midpoint rule: exact here.
    double total = 0;
    for (int c = 0; c < cells; ++c)
        total += probability[c] = d.pdf_continuous((c + 0.5f) / cells) / cells;
    EXPECT_NEAR(total, 1.0, 1e-6);
    ChiSquareResult r = chi_square_test_discrete(family, observed, probability, kSamples);
    EXPECT_TRUE(r.passed) << r.message;
    // Density is weight / integral.
    for (int i = 0; i < n; ++i)
        EXPECT_FLOAT_EQ(d.pdf_continuous((i + 0.5f) / n), kWeights[i] / d.integral());
    EXPECT_EQ(d.pdf_continuous(-0.1f), 0.0f);
    EXPECT_EQ(d.pdf_continuous(1.0f), 0.0f);
    // The end points of u stay inside [0, 1) and in bins of non-zero weight.
    for (float u : {0.0f, kOneMinusEpsilon}) {
        float x = d.sample_continuous(u);
        EXPECT_GE(x, 0.0f);
        EXPECT_LT(x, 1.0f);
        EXPECT_GT(d.pdf_continuous(x), 0.0f) << "u = " << u;
    }
}

TEST(Distribution1D, AllZeroWeightsFallBackToUniform) {
    Distribution1D d(std::vector<float>(5, 0.0f));
    for (size_t i = 0; i < 5; ++i) EXPECT_FLOAT_EQ(d.discrete_probability(i), 0.2f);
    for (float u : {0.0f, 0.3f, 0.5f, kOneMinusEpsilon}) {
        float pdf;
        float x = d.sample_continuous(u, &pdf);
        EXPECT_FLOAT_EQ(pdf, 1.0f);
        EXPECT_NEAR(x, u, 1e-6f);
    }
    // Non-finite and negative weights count as zero.
    Distribution1D e({-1.0f, std::nanf(""), 2.0f, kInfinity});
    EXPECT_FLOAT_EQ(e.discrete_probability(2), 1.0f);
    EXPECT_EQ(e.sample_discrete(0.0f), 2u);
    EXPECT_EQ(e.sample_discrete(kOneMinusEpsilon), 2u);
}

TEST(Distribution1D, SingleBin) {
    Distribution1D d({4.0f});
    EXPECT_FLOAT_EQ(d.integral(), 4.0f);
    EXPECT_FLOAT_EQ(d.discrete_probability(0), 1.0f);
    for (float u : {0.0f, 0.25f, kOneMinusEpsilon}) {
        float probability, pdf;
        EXPECT_EQ(d.sample_discrete(u, &probability), 0u);
        EXPECT_FLOAT_EQ(probability, 1.0f);
        EXPECT_FLOAT_EQ(d.sample_continuous(u, &pdf), u);
        EXPECT_FLOAT_EQ(pdf, 1.0f);
    }
}

// A 6 x 5 map with a zero row, zero texels and one dominant texel.
std::vector<float> map_weights() {
    std::vector<float> w(6 * 5);
    for (int y = 0; y < 5; ++y)
        for (int x = 0; x < 6; ++x) w[y * 6 + x] = float((x * 7 + y * 3) % 5);
    for (int x = 0; x < 6; ++x) w[2 * 6 + x] = 0.0f;  // an all-black row
    w[4 * 6 + 1] = 40.0f;
    return w;
}

// Histogram of Distribution2D samples on a grid aligned with the texels (k x k cells per
// texel), against the cell probabilities of the claimed pdf (midpoint rule, exact for a
// piecewise-constant density).
// A sample outside the unit square or with a pdf other than pdf_a() reports fails the test.
ChiSquareResult chi_square_2d(const Distribution2D& d, int width, int height, int k,
                              uint64_t seed) {
    const int nx = width * k, ny = height * k;
    std::vector<double> observed(size_t(nx * ny), 0.0), probability(size_t(nx * ny));
    Rng rng(StreamKey{seed, 0, 1, 0});
    for (int i = 0; i < kSamples; ++i) {
        float pdf;
        Vec2 p = d.sample(rng.next_2d(), &pdf);
        if (!(p.x >= 0 && p.x < 1 && p.y >= 0 && p.y < 1) || !(pdf > 0) ||
            std::abs(pdf - d.pdf_a(p)) > 1e-5f * pdf) {
            ADD_FAILURE() << "bad sample (" << p.x << ", " << p.y << ") with pdf " << pdf
                          << " (pdf_a() says " << d.pdf_a(p) << ")";
            break;
        }
        observed[size_t(std::min(int(p.y * ny), ny - 1) * nx + std::min(int(p.x * nx), nx - 1))] +=
            1;
    }
    for (int y = 0; y < ny; ++y)
        for (int x = 0; x < nx; ++x)
            probability[size_t(y * nx + x)] =
                d.pdf_a(Vec2((x + 0.5f) / nx, (y + 0.5f) / ny)) / (double(nx) * ny);
    return chi_square_test_discrete(family, observed, probability, kSamples);
}

CHI_SQUARE_TEST(family, Distribution2D, ChiSquare, 1) {
    Distribution2D d(map_weights(), 6, 5);
    ChiSquareResult r = chi_square_2d(d, 6, 5, 2, 3);
    EXPECT_TRUE(r.passed) << r.message;
}

TEST(Distribution2D, PdfIsNormalisedWeights) {
    std::vector<float> w = map_weights();
    Distribution2D d(w, 6, 5);
    double sum = std::accumulate(w.begin(), w.end(), 0.0), integral = 0;
    for (int y = 0; y < 5; ++y)
        for (int x = 0; x < 6; ++x) {
            Vec2 p((x + 0.5f) / 6, (y + 0.5f) / 5);
            // pdf_a w.r.t. the unit square = weight / (sum / cells).
            EXPECT_NEAR(d.pdf_a(p), w[y * 6 + x] / (sum / 30.0), 1e-5) << x << ", " << y;
            integral += d.pdf_a(p) / 30.0;
        }
    EXPECT_NEAR(integral, 1.0, 1e-6);
    EXPECT_EQ(d.pdf_a(Vec2(0.5f, 1.0f)), 0.0f);
    EXPECT_EQ(d.pdf_a(Vec2(0.5f, -0.1f)), 0.0f);
    for (Vec2 u :
         {Vec2(0, 0), Vec2(kOneMinusEpsilon, kOneMinusEpsilon), Vec2(0, kOneMinusEpsilon)}) {
        float pdf;
        Vec2 p = d.sample(u, &pdf);
        EXPECT_GT(pdf, 0.0f);
        EXPECT_TRUE(p.x >= 0 && p.x < 1 && p.y >= 0 && p.y < 1);
    }
}

CHI_SQUARE_TEST(family, Distribution2D, AllZeroIsUniform, 1) {
    Distribution2D d(std::vector<float>(4 * 3, 0.0f), 4, 3);
    ChiSquareResult r = chi_square_2d(d, 4, 3, 2, 4);
    EXPECT_TRUE(r.passed) << r.message;
    EXPECT_NEAR(d.pdf_a(Vec2(0.3f, 0.7f)), 1.0f, 1e-6f);
}

}  // namespace
}  // namespace render::testing
