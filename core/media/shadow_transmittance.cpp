#include "core/media/shadow_transmittance.h"

#include <cmath>

#include "core/media/medium.h"
#include "core/media/medium_interface.h"
#include "core/scene/scene.h"

namespace render {
namespace {
// Stacked index-matched boundaries are crossed one by one; this many means a modelling error
// (or coincident surfaces), and the light is treated as blocked rather than looping.
constexpr int kMaxNullCrossings = 256;
}  // namespace

Rgb shadow_transmittance(const Scene& scene, const Ray& shadow_ray, const Medium* medium, Rng& rng,
                         uint64_t& rays) {
    Rgb tr(1.0f);
    Ray ray = shadow_ray;
    const bool to_infinity = std::isinf(ray.t_max);
    const Vec3 end = to_infinity ? Vec3() : ray.at(ray.t_max);
    for (int crossing = 0; crossing <= kMaxNullCrossings; ++crossing) {
        SurfaceInteraction si;
        ++rays;
        if (!scene.intersect(ray, si)) {
            if (medium) tr *= medium->transmittance(ray, ray.t_max, rng);
            return tr;
        }
        if (!si.bsdf->is_null()) return Rgb(0.0f);
        if (medium) tr *= medium->transmittance(ray, si.t, rng);
        if (tr.is_black()) return tr;
        medium = medium_after_transmission(si, ray.direction);
        const Ray next = scene.spawn_ray(si.p, si.geometric_normal, ray.direction);
        const float remaining = to_infinity ? kInfinity : dot(end - next.origin, ray.direction);
        if (!(remaining > 0)) return tr;
        ray = Ray(next.origin, ray.direction, 0.0f, remaining);
    }
    return Rgb(0.0f);
}

}  // namespace render
