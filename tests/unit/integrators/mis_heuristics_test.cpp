// The power heuristics of core/integrators/mis.h (used by pt, volpt and its joint sampling):
// for any densities of the techniques that can produce a path, the weights of those techniques
// sum to one, techniques with density 0 get weight 0, and squares of huge densities never
// overflow into NaN. Fixed seed; the tolerance 1e-5 is float rounding of a sum of <= 4 terms.

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <random>

#include "core/integrators/mis.h"

namespace render {
namespace {

// A density in [1e-30, 1e30] (log-uniform), or 0 with probability 1/4.
double random_density(std::mt19937_64& rng) {
    std::uniform_real_distribution<double> u(0.0, 1.0);
    if (u(rng) < 0.25) return 0.0;
    return std::pow(10.0, -30.0 + 60.0 * u(rng));
}

TEST(MisHeuristics, PowerHeuristicsArePartitionsOfUnity) {
    std::mt19937_64 rng(20261125);
    for (int trial = 0; trial < 100000; ++trial) {
        std::array<double, 4> p;
        for (double& x : p) x = random_density(rng);
        if (p[0] == 0 && p[1] == 0 && p[2] == 0 && p[3] == 0) continue;  // no technique
        const double w4 = double(power_heuristic4(p[0], p[1], p[2], p[3])) +
                          power_heuristic4(p[1], p[0], p[2], p[3]) +
                          power_heuristic4(p[2], p[0], p[1], p[3]) +
                          power_heuristic4(p[3], p[0], p[1], p[2]);
        ASSERT_NEAR(w4, 1.0, 1e-5) << p[0] << " " << p[1] << " " << p[2] << " " << p[3];
        for (int i = 0; i < 4; ++i)
            if (p[i] == 0) {
                ASSERT_EQ(power_heuristic4(p[i], p[(i + 1) % 4], p[(i + 2) % 4], p[(i + 3) % 4]),
                          0.0f);
            }
        // Three and two techniques (float densities: stay inside float's range).
        const float a = float(p[0] * 1e-8), b = float(p[1] * 1e-8), c = float(p[2] * 1e-8);
        if (a > 0 || b > 0 || c > 0) {
            const double w3 = double(power_heuristic3(a, b, c)) + power_heuristic3(b, a, c) +
                              power_heuristic3(c, a, b);
            ASSERT_NEAR(w3, 1.0, 1e-5) << a << " " << b << " " << c;
        }
        if (a > 0 || b > 0) {
            ASSERT_NEAR(double(power_heuristic(a, b)) + power_heuristic(b, a), 1.0, 1e-5)
                << a << " " << b;
        }
    }
}

}  // namespace
}  // namespace render
