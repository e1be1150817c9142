#pragma once

// Direct illumination from a light concentrated at one point (point and spot lights): the unit
// direction and distance from the receiver `ref`, the solid-angle density d^2 of having
// "sampled" the delta position, and cos = 1 at the light. False when ref is on the light (no
// direction) or the distance is not finite. The caller sets radiance and emission density.

#include <cmath>

#include "core/lights/light.h"

namespace render {

inline bool illuminate_from_point(const Vec3& position, const Vec3& ref,
                                  LightIlluminateSample& out) {
    const Vec3 to_light = position - ref;
    const float d2 = length_squared(to_light);
    if (!(d2 > 0) || !std::isfinite(d2)) return false;
    const float d = std::sqrt(d2);
    out.wi = to_light / d;
    out.distance = d;
    out.pdf_direct_w = d2;
    out.cos_at_light = 1.0f;
    return true;
}

}  // namespace render
