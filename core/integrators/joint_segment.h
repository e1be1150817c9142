#pragma once

// J2, the segment-segment joint connection of bpt (docs/design/media.md, "J2: segment-segment
// connections"): the density with which B2 (core/sampling/joint_light_distance.h) samples a
// light-side vertex x on the light ray from `light_origin` through it, given the eye ray from
// `eye_origin` through `eye_through` (the eye-side vertex, sampled afterwards by J1). The range
// is the light ray's exit from the scene's bounding sphere, so every technique evaluates the same
// density from the path's vertices alone, without tracing.

#include <cmath>

#include "core/lights/light.h"
#include "core/math/vec.h"
#include "core/sampling/joint_light_distance.h"

namespace render {

// B2's range on the light ray from `origin` along unit `direction`: up to where it leaves the
// scene's bounding sphere (0 when it never is inside). Deterministic from the ray alone, so
// that the density of a path's light-side vertex can be evaluated by every technique without
// tracing (ALGORITHMS-NEXT.md rule 0.3).
inline float light_ray_range(const SceneSphere& sphere, const Vec3& origin, const Vec3& direction) {
    const double o[3] = {double(origin.x) - sphere.center.x, double(origin.y) - sphere.center.y,
                         double(origin.z) - sphere.center.z};
    const double b = o[0] * direction.x + o[1] * direction.y + o[2] * direction.z;
    const double c =
        o[0] * o[0] + o[1] * o[1] + o[2] * o[2] - double(sphere.radius) * sphere.radius;
    const double disc = b * b - c;
    if (!(disc > 0)) return 0.0f;
    const double t = -b + std::sqrt(disc);
    return t > 0 && std::isfinite(t) ? float(t) : 0.0f;
}

inline float joint2_pdf_l(const SceneSphere& sphere, const Vec3& light_origin, const Vec3& x,
                          const Vec3& eye_origin, const Vec3& eye_through) {
    const Vec3 d = x - light_origin, e = eye_through - eye_origin;
    const float t = length(d), s = length(e);
    if (!(t > 0) || !(s > 0)) return 0.0f;
    const Vec3 w = d / t;
    const float range = light_ray_range(sphere, light_origin, w);
    if (!(range > 0)) return 0.0f;
    return JointLightDistanceSampler(light_origin, w, eye_origin, e / s, range).pdf_l(t);
}

}  // namespace render
