#include "core/integrators/eyelight.h"

namespace render {

Rgb EyeLight::Li(const Scene& scene, const Ray& ray, Rng&, RenderStats& stats,
                 const LayerSink&) const {
    SurfaceInteraction si(kUnfilled);
    ++stats.rays;
    if (!scene.intersect(ray, si)) return Rgb(0.0f);
    return Rgb(abs_dot(si.shading.n, ray.direction));
}

}  // namespace render
