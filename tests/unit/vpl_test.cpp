// Many-light rendering (vpl) and its importance-driven VPL distribution: exact identities that
// need no statistics. (Convergence against pt and between the distributions is in
// convergence_test; furnace and iteration contract in render_test, as for every algorithm.)

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>

#include "core/integrators/vpl_distribution.h"
#include "core/render/render_iterations.h"
#include "core/render/render_options.h"
#include "core/scene/loader/scene_loader.h"

namespace render {
namespace {

// The acceptance probabilities, exactly: four candidates with contributions 6, 2, 1, 1 (sum 10,
// M = 4): P = min(4 phi_k / 10, 1) floored at P_min.
TEST(VplDistribution, KeepProbabilitiesFollowTheFormula) {
    const std::vector<double> p = vpl_keep_probabilities({6, 2, 1, 1}, 0.05);
    ASSERT_EQ(p.size(), 4u);
    EXPECT_DOUBLE_EQ(p[0], 1.0);  // 2.4, above average: always kept
    EXPECT_DOUBLE_EQ(p[1], 0.8);
    EXPECT_DOUBLE_EQ(p[2], 0.4);
    EXPECT_DOUBLE_EQ(p[3], 0.4);
    // A VPL no record sees is kept with P_min (never 0: that would be biased).
    EXPECT_EQ(vpl_keep_probabilities({5, 0}, 0.05), (std::vector<double>{1.0, 0.05}));
    // Nothing seen at all: no basis for a choice, keep everything.
    EXPECT_EQ(vpl_keep_probabilities({0, 0, 0}, 0.05), (std::vector<double>(3, 1.0)));
    // Non-finite or negative estimates count as 0.
    const double nan = std::nan(""), inf = INFINITY;
    EXPECT_EQ(vpl_keep_probabilities({1, nan, inf, -3}, 0.1),
              (std::vector<double>{1.0, 0.1, 0.1, 0.1}));
    // P_min = 1 keeps every candidate.
    EXPECT_EQ(vpl_keep_probabilities({9, 1, 0}, 1.0), (std::vector<double>(3, 1.0)));
}

// In expectation the distribution keeps sum P_k VPLs: at least one (the largest phi_k is at
// least the average), at most M.
TEST(VplDistribution, TheLargestContributionIsAlwaysKept) {
    for (const std::vector<double>& phi :
         {std::vector<double>{1e-30, 1e-29, 3e-30}, std::vector<double>{1, 1, 1, 1},
          std::vector<double>{1e6, 1, 1e-6}}) {
        const std::vector<double> p = vpl_keep_probabilities(phi, 1e-9);
        const size_t largest = size_t(std::max_element(phi.begin(), phi.end()) - phi.begin());
        EXPECT_EQ(p[largest], 1.0);
        for (double x : p) EXPECT_TRUE(x > 0 && x <= 1) << x;
    }
}

std::unique_ptr<Scene> two_rooms() {
    return load_scene(std::string(RENDER_SOURCE_DIR) + "/scenes/tests/two-rooms.xml",
                      {{"resx", "24"}, {"resy", "24"}});
}

IterationResult render(const Scene& scene, const OptionMap& options, uint64_t first, uint64_t end,
                       int threads = 0) {
    RenderSettings settings = resolve_render_settings("vpl", options, scene.settings);
    settings.seed = 5;
    settings.threads = threads;
    return render_iterations(scene, settings, 0, IterationRange{first, end});
}

// With P_min = 1 every candidate is kept with probability 1 and weight 1: the importance pass
// (records, their shadow rays) must not change a single pixel, since it draws from streams of
// its own.
TEST(Vpl, ImportanceWithMinimumProbabilityOneIsTheUniformImage) {
    auto scene = two_rooms();
    const IterationResult uniform = render(*scene, {}, 1, 3);
    const IterationResult importance =
        render(*scene, {{"vpl_distribution", "importance"}, {"vpl_min_probability", "1"}}, 1, 3);
    EXPECT_EQ(importance.sum.values(), uniform.sum.values());
    EXPECT_EQ(importance.stats.vpl_accepted, importance.stats.vpl_candidates);
    EXPECT_GT(importance.stats.vpl_candidates, 0u);
    EXPECT_EQ(uniform.stats.vpl_candidates, 0u) << "uniform VPLs are not counted as candidates";
}

// On two-rooms most VPLs light the room the camera does not see: the distribution keeps a
// minority of them (the paper reports 7-33 % on its scenes), at least P_min of them in
// expectation, and never more than all.
TEST(Vpl, ImportanceKeepsFewVplsWhenTheLightIsAroundTheCorner) {
    auto scene = two_rooms();
    const IterationResult r = render(*scene, {{"vpl_distribution", "importance"}}, 1, 9);
    ASSERT_GT(r.stats.vpl_candidates, 100u);
    const double acceptance = double(r.stats.vpl_accepted) / double(r.stats.vpl_candidates);
    EXPECT_LT(acceptance, 0.6);
    EXPECT_GT(acceptance, 0.05 * 0.5);  // P_min = 0.05; half of it leaves room for chance
    EXPECT_EQ(r.stats.non_finite, 0u);
}

// The iteration contract with the importance pass: thread counts and split ranges give the same
// image (the records, estimates and draws are keyed by iteration and index, never by thread).
TEST(Vpl, ImportanceDistributionKeepsTheIterationContract) {
    auto scene = two_rooms();
    const OptionMap importance = {{"vpl_distribution", "importance"}};
    const IterationResult one_thread = render(*scene, importance, 1, 5, 1);
    const IterationResult two_threads = render(*scene, importance, 1, 5, 2);
    EXPECT_EQ(one_thread.sum.values(), two_threads.sum.values());
    const IterationResult first = render(*scene, importance, 1, 3, 2);
    const IterationResult second = render(*scene, importance, 3, 5, 2);
    for (size_t i = 0; i < one_thread.sum.values().size(); ++i)
        ASSERT_NEAR(first.sum.values()[i] + second.sum.values()[i], one_thread.sum.values()[i],
                    1e-9 * std::abs(one_thread.sum.values()[i]) + 1e-12);
}

// Clamping the distance of the geometry term only ever removes energy (near touching surfaces).
TEST(Vpl, AFixedClampNeverBrightensAPixel) {
    auto scene = load_scene(
        std::string(RENDER_SOURCE_DIR) + "/scenes/bitterli/cornell-box/scene_v3.xml", {});
    scene->set_camera(scene->camera().with_resolution(24, 24));
    const IterationResult unclamped = render(*scene, {}, 1, 2);
    const IterationResult clamped =
        render(*scene, {{"vpl_clamp", "0.2"}, {"vpl_clamp_schedule", "fixed"}}, 1, 2);
    double lost = 0;
    for (size_t i = 0; i < unclamped.sum.values().size(); ++i) {
        // Same VPLs, same shadow rays: each term can only shrink (float rounding aside).
        EXPECT_LE(clamped.sum.values()[i], unclamped.sum.values()[i] * (1 + 1e-5) + 1e-9);
        lost += unclamped.sum.values()[i] - clamped.sum.values()[i];
    }
    EXPECT_GT(lost, 0.0) << "a clamp of 20 % of the scene radius must remove something";
}

// Candidates are never all rejected: the VPL with the largest estimate has M phi_k / phi >= 1,
// so it is kept with probability 1; when no record sees any VPL (phi = 0) every candidate is
// kept. Checked iteration by iteration, with a P_min so small that anything else would show.
TEST(Vpl, EveryIterationKeepsAtLeastOneCandidate) {
    auto scene = two_rooms();
    for (uint64_t i = 1; i <= 16; ++i) {
        const IterationResult r = render(*scene,
                                         {{"vpl_distribution", "importance"},
                                          {"vpl_min_probability", "1e-9"},
                                          {"importance_records", "3"}},
                                         i, i + 1);
        if (r.stats.vpl_candidates > 0) {
            EXPECT_GE(r.stats.vpl_accepted, 1u) << "iteration " << i;
        }
        EXPECT_EQ(r.stats.non_finite, 0u);
    }
}

// Unclamped connections to VPLs next to the shading point (the Cornell box's corners: the
// distance goes to 0 and G to infinity) stay finite: the estimator is unbiased with infinite
// variance there, but no sample may be NaN or Inf.
TEST(Vpl, VplsAtTouchingSurfacesGiveFiniteSamples) {
    auto scene = load_scene(
        std::string(RENDER_SOURCE_DIR) + "/scenes/bitterli/cornell-box/scene_v3.xml", {});
    scene->set_camera(scene->camera().with_resolution(32, 32));
    const IterationResult r = render(*scene, {{"vpl_paths", "512"}}, 1, 5);
    EXPECT_EQ(r.stats.non_finite, 0u);
    for (double v : r.sum.values()) ASSERT_TRUE(std::isfinite(v) && v >= 0);
}

}  // namespace
}  // namespace render
