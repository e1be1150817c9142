#include <tbb/blocked_range2d.h>
#include <tbb/combinable.h>
#include <tbb/parallel_for.h>

#include "core/integrators/integrator.h"

namespace render {

void PixelIntegrator::render_iteration(const Scene& scene, const IterationKey& key,
                                       AccumulationBuffer& target, TechniqueLayers* layers,
                                       RenderStats& stats) const {
    const PerspectiveCamera& camera = scene.camera();
    const int width = camera.width(), height = camera.height();
    tbb::combinable<RenderStats> tile_stats;
    constexpr int kTile = 16;
    // Every pixel is written by exactly one task, and its value depends only on its own
    // random stream: the image is identical for any number of threads.
    tbb::parallel_for(
        tbb::blocked_range2d<int>(0, height, kTile, 0, width, kTile),
        [&](const tbb::blocked_range2d<int>& tile) {
            RenderStats& local = tile_stats.local();
            for (int y = tile.rows().begin(); y < tile.rows().end(); ++y)
                for (int x = tile.cols().begin(); x < tile.cols().end(); ++x) {
                    size_t pixel = size_t(y) * width + x;
                    Rng rng(StreamKey{key.seed, key.frame, key.iteration, pixel});
                    Vec2 jitter = rng.next_2d();
                    Ray ray = camera.generate_ray(Vec2(float(x) + jitter.x, float(y) + jitter.y));
                    Rgb L = Li(scene, ray, rng, local, LayerSink{layers, pixel});
                    ++local.samples;
                    if (!L.is_finite()) {
                        ++local.non_finite;
                        continue;
                    }
                    target.add(pixel, L);
                }
        },
        tbb::simple_partitioner());
    tile_stats.combine_each([&](const RenderStats& s) { stats += s; });
}

}  // namespace render
