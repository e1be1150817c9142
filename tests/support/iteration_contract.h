#pragma once

// The iteration contract (docs/design/architecture.md) checked on a given scene and settings, for
// the tests that add a scene kind to render_test's contract cases (grid_photon_beams_test,
// volume_emitter_test). Call under ASSERT_NO_FATAL_FAILURE: the checks stop at the first
// element that differs.

#include <gtest/gtest.h>

#include <cmath>
#include <utility>

#include "core/render/render_iterations.h"
#include "core/scene/scene.h"

namespace render::testing {

// Rendering [first, end) in one piece equals [first, split) plus [split, end): only the order
// of the double additions differs (1e-12 relative). `whole`, if given, receives the one piece.
inline void expect_split_ranges_add_up(const Scene& scene, const RenderSettings& settings,
                                       uint64_t first, uint64_t split, uint64_t end,
                                       IterationResult* whole_out = nullptr) {
    IterationResult whole = render_iterations(scene, settings, 0, IterationRange{first, end});
    const IterationResult a = render_iterations(scene, settings, 0, IterationRange{first, split});
    const IterationResult b = render_iterations(scene, settings, 0, IterationRange{split, end});
    for (size_t i = 0; i < whole.sum.values().size(); ++i) {
        const double sum = a.sum.values()[i] + b.sum.values()[i];
        ASSERT_NEAR(whole.sum.values()[i], sum, 1e-12 * std::abs(sum) + 1e-300);
    }
    if (whole_out) *whole_out = std::move(whole);
}

// One IterationRenderer over `range` with 1 and with 2 threads: the same rays, the same sums bit
// for bit.
inline void expect_thread_count_changes_nothing(const Scene& scene, RenderSettings settings,
                                                IterationRange range) {
    auto render_with = [&](int threads) {
        settings.threads = threads;
        IterationRenderer renderer(scene, settings, /*frame=*/2);
        IterationResult result = renderer.empty_result();
        renderer.add(range, result);
        return result;
    };
    const IterationResult one = render_with(1), two = render_with(2);
    EXPECT_EQ(one.stats.rays, two.stats.rays);
    EXPECT_TRUE(one.sum.values() == two.sum.values());
}

}  // namespace render::testing
