#pragma once

// The first step of every next-event estimation: pick a light by power, then a point on it as
// seen from the receiver. Path tracing, volumetric path tracing and the bidirectional family
// all start their light-sampling technique here (and draw the same random numbers in the same
// order: one for the light, two for the point).

#include <cmath>

#include "core/lights/light.h"
#include "core/sampling/rng.h"
#include "core/scene/scene.h"

namespace render {

struct DirectLightSample {
    const Light* light = nullptr;
    float pick_probability = 0;  // the light's selection probability (discrete)
    LightIlluminateSample ls;
    // Selection probability times the light's solid-angle density at the receiver.
    float pdf_w() const { return pick_probability * ls.pdf_direct_w; }
    // The shadow ray from receiver p (geometric normal n; zero in a medium) to the sample.
    Ray shadow_ray(const Scene& scene, const Vec3& p, const Vec3& n) const {
        return std::isinf(ls.distance) ? scene.spawn_ray_to_infinity(p, n, ls.wi)
                                       : scene.spawn_ray_to(p, n, p + ls.wi * ls.distance, Vec3());
    }
};

// False when there is nothing to connect to (no light, or a sample without energy or density).
inline bool sample_direct_light(const Scene& scene, const Vec3& receiver, Rng& rng,
                                DirectLightSample& out) {
    out.light = scene.sample_light(rng.next_1d(), &out.pick_probability);
    const Vec2 u = rng.next_2d();
    return out.light && out.pick_probability > 0 && out.light->illuminate(receiver, u, out.ls) &&
           out.ls.pdf_direct_w > 0;
}

}  // namespace render
