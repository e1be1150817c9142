// What the importance-caching claims measure (docs/reference/algorithms.md, "What the variance
// ratio against power sampling measures"): with the same seed, `ic` and `vpl` render the same
// VPLs and the same next-event estimation, so an ic image less the vpl image of the same seed
// and iteration is the VPL sampling's error alone. scripts/benchlib/claims.py relies on it.

#include <gtest/gtest.h>

#include <string>

#include "core/render/render_iterations.h"
#include "core/render/render_options.h"
#include "core/scene/loader/scene_loader.h"

namespace render {
namespace {

IterationResult render_one(const Scene& scene, const std::string& algorithm, uint64_t seed,
                           uint64_t iteration) {
    const OptionMap options = {{"vpl_clamp", "0.01"}, {"vpl_clamp_schedule", "fixed"}};
    RenderSettings settings = resolve_render_settings(algorithm, options, scene.settings);
    settings.seed = seed;
    settings.threads = 1;
    return render_iterations(scene, settings, 0, IterationRange{iteration, iteration + 1});
}

double squared_difference(const IterationResult& a, const IterationResult& b) {
    const auto& x = a.sum.values();
    const auto& y = b.sum.values();
    double sum = 0;
    for (size_t i = 0; i < x.size(); ++i) sum += (double(x[i]) - y[i]) * (double(x[i]) - y[i]);
    return sum;
}

// Paired (same seed) the difference holds the sampling error only; unpaired it also holds two
// VPL sets' and two next-event estimations' errors. On two-rooms the VPL set's variance is
// several times ic's sampling variance (docs/results/claims.md), so the paired sum is far below
// the unpaired one; the bar (half) leaves a wide margin. If ic traced other light paths than
// vpl (another stream, path count or roulette), both sums would be alike and this fails.
TEST(ImportanceCaching, SharesTheVplsAndNextEventEstimationOfVpl) {
    auto scene = load_scene(std::string(RENDER_SOURCE_DIR) + "/scenes/tests/two-rooms.xml",
                            {{"resx", "24"}, {"resy", "24"}});
    double paired = 0, unpaired = 0;
    for (uint64_t i = 1; i <= 8; ++i) {
        const IterationResult ic = render_one(*scene, "ic", 5, i);
        paired += squared_difference(ic, render_one(*scene, "vpl", 5, i));
        unpaired += squared_difference(ic, render_one(*scene, "vpl", 6, i));
    }
    EXPECT_GT(paired, 0.0) << "ic must not be vpl itself";
    EXPECT_LT(paired, 0.5 * unpaired) << "paired " << paired << ", unpaired " << unpaired;
}

}  // namespace
}  // namespace render
