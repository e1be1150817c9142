// Russian roulette by albedo (core/integrators/roulette.h): a weight of at least 1 in its
// largest channel never ends a path and draws no number; below 1 the path survives with
// probability max(weight) and its throughput is divided by it, so the expected throughput is
// unchanged; a zero or NaN weight ends the path.

#include <gtest/gtest.h>

#include <cmath>

#include "core/integrators/roulette.h"

namespace render {
namespace {

TEST(Roulette, AWeightOfOneOrMoreNeverEndsAPathAndDrawsNothing) {
    Rng rng(StreamKey{.seed = 1});
    Rng untouched(StreamKey{.seed = 1});
    Rgb throughput(0.3f, 0.2f, 0.1f);
    EXPECT_TRUE(survives_albedo_roulette(Rgb(1.0f, 0.2f, 0.0f), throughput, rng));
    EXPECT_TRUE(survives_albedo_roulette(Rgb(0.1f, 3.0f, 0.5f), throughput, rng));
    EXPECT_EQ(throughput.r, 0.3f);
    EXPECT_EQ(rng.next_u32(), untouched.next_u32());
}

TEST(Roulette, ZeroOrNanWeightsEndThePath) {
    Rng rng(StreamKey{.seed = 2});
    Rgb throughput(1.0f);
    EXPECT_FALSE(survives_albedo_roulette(Rgb(0.0f), throughput, rng));
    EXPECT_FALSE(survives_albedo_roulette(Rgb(NAN, NAN, NAN), throughput, rng));
}

// Survival with probability q = 0.3 and throughput / q: the mean of the throughput after
// roulette (0 for ended paths) is the throughput before, within 5 standard errors (n = 200000:
// the standard error of the mean is sqrt(q (1 - q)) / q / sqrt(n) = 0.0034 of it); a survivor
// not divided by q (mean 0.3) or divided by q twice (mean 3.3) fails by far.
TEST(Roulette, TheExpectedThroughputIsUnchanged) {
    const float q = 0.3f;
    const int n = 200000;
    Rng rng(StreamKey{.seed = 3});
    double sum = 0, survived = 0;
    for (int i = 0; i < n; ++i) {
        Rgb throughput(1.0f);
        if (survives_albedo_roulette(Rgb(q, 0.1f, 0.2f), throughput, rng)) {
            sum += throughput.r;
            survived += 1;
        }
    }
    const double se = std::sqrt(q * (1 - q)) / q / std::sqrt(double(n));
    EXPECT_NEAR(sum / n, 1.0, 5 * se);
    EXPECT_NEAR(survived / n, q, 5 * std::sqrt(q * (1 - q) / n));
}

}  // namespace
}  // namespace render
