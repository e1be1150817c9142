#pragma once

// The eye pass shared by every integrator: one estimate per pixel, in 16 x 16 tiles over TBB.
// Every pixel is written by exactly one task and its value depends only on its own random
// stream, so the image is identical for any number of threads. A non-finite estimate is
// counted and dropped, never added.

#include <tbb/blocked_range2d.h>
#include <tbb/combinable.h>
#include <tbb/parallel_for.h>

#include <cstdint>
#include <utility>

#include "core/base/render_stats.h"
#include "core/image/image.h"

namespace render {

// estimate(pixel, stats) returns the pixel's estimate and counts the rays it traces in stats.
// With `active` (one entry per pixel; adaptive sampling, docs/reference/adaptive-sampling.md),
// a pixel whose entry is 0 is skipped: no estimate, no sample, its target value untouched.
// Skipping draws no random numbers from other pixels' streams, so the active pixels' values are
// those of a render without the mask.
template <typename Estimate>
void for_each_pixel(int width, int height, AccumulationBuffer& target, RenderStats& stats,
                    const uint8_t* active, Estimate&& estimate) {
    constexpr int kTile = 16;
    tbb::combinable<RenderStats> tile_stats;
    tbb::parallel_for(
        tbb::blocked_range2d<int>(0, height, kTile, 0, width, kTile),
        [&](const tbb::blocked_range2d<int>& tile) {
            RenderStats& local = tile_stats.local();
            for (int y = tile.rows().begin(); y < tile.rows().end(); ++y)
                for (int x = tile.cols().begin(); x < tile.cols().end(); ++x) {
                    const uint64_t pixel = uint64_t(y) * uint64_t(width) + uint64_t(x);
                    if (active && !active[pixel]) continue;
                    const Rgb value = estimate(pixel, local);
                    ++local.samples;
                    if (!value.is_finite()) {
                        ++local.non_finite;
                        continue;
                    }
                    target.add(pixel, value);
                }
        },
        tbb::simple_partitioner());
    tile_stats.combine_each([&](const RenderStats& s) { stats += s; });
}

template <typename Estimate>
void for_each_pixel(int width, int height, AccumulationBuffer& target, RenderStats& stats,
                    Estimate&& estimate) {
    for_each_pixel(width, height, target, stats, nullptr, std::forward<Estimate>(estimate));
}

}  // namespace render
