#include "core/integrators/integrator.h"
#include "core/integrators/pixel_loop.h"

namespace render {

void PixelIntegrator::render_iteration(const Scene& scene, const IterationKey& key,
                                       AccumulationBuffer& target, TechniqueLayers* layers,
                                       RenderStats& stats) const {
    const PerspectiveCamera& camera = scene.camera();
    const int width = camera.width();
    for_each_pixel(width, camera.height(), target, stats, active_pixels(),
                   [&](uint64_t pixel, RenderStats& local) {
                       Rng rng(StreamKey{key.seed, key.frame, key.iteration, pixel});
                       const Vec2 jitter = rng.next_2d();
                       const Ray ray = camera.sample_ray(
                           Vec2(float(pixel % width) + jitter.x, float(pixel / width) + jitter.y),
                           rng);
                       return Li(scene, ray, rng, local, LayerSink{layers, pixel});
                   });
}

}  // namespace render
