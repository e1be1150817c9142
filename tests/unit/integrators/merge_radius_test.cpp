#include "core/integrators/merge_radius.h"

#include <gtest/gtest.h>

#include <cmath>

namespace render {
namespace {

TEST(MergeRadius, MatchesItsFormula) {
    for (double alpha : {0.5, 0.75, 1.0})
        for (uint64_t i : {1ull, 2ull, 7ull, 1000ull, 123456789ull})
            EXPECT_NEAR(merge_radius(0.25, alpha, i), 0.25 * std::pow(double(i), (alpha - 1) / 2),
                        1e-15);
    EXPECT_EQ(merge_radius(0.3, 0.75, 1), 0.3);
}

TEST(MergeRadius, IsMonotoneAndFloored) {
    double previous = merge_radius(1.0, 0.75, 1);
    for (uint64_t i = 2; i < 100000; i += 97) {
        double r = merge_radius(1.0, 0.75, i);
        EXPECT_LE(r, previous);
        previous = r;
    }
    // alpha = 1 keeps the radius; a huge iteration index hits the floor, never zero.
    EXPECT_EQ(merge_radius(2.0, 1.0, 1000000), 2.0);
    // A scene of size 1e-12 after 2^64 iterations would reach 1e-21: the floor holds.
    double floor = merge_radius(1e-12, 0.01, ~0ull);
    EXPECT_EQ(floor, min_merge_radius());
    EXPECT_GT(floor, 0.0);
    EXPECT_TRUE(std::isfinite(float(1.0 / (M_PI * floor * floor))));
}

}  // namespace
}  // namespace render
