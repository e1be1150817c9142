#pragma once

// Visibility through media: the fraction of light that survives a shadow ray. The ray steps
// through index-matched (null) surfaces, switching media as a path would, multiplies the
// transmittance of every medium it crosses, and is blocked by any other surface.

#include <cstdint>

#include "core/math/ray.h"
#include "core/math/vec.h"
#include "core/sampling/rng.h"

namespace render {

class Medium;
class Scene;

// `ray` is a shadow ray as Scene::spawn_ray_to builds it (the segment (t_min, t_max) must be
// free of blockers); `medium` is the medium at its origin. `rays` counts the queries traced.
Rgb shadow_transmittance(const Scene& scene, const Ray& ray, const Medium* medium, Rng& rng,
                         uint64_t& rays);

}  // namespace render
