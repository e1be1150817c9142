#pragma once

// The limits of what a scene may describe, in one place (the loaders, the lights and the scene
// check against these).

#include <cmath>

#include "core/math/vec.h"

namespace render {

// Geometry our float arithmetic and Embree can handle: finite bounds within
// kMaxSceneCoordinate of the origin and a finite area. A transform such as a scale of 1e30
// would otherwise overflow ray offsets and light densities into non-finite rays, which Embree
// asserts on (the process aborts: a worker would die on the scene, again and again). The
// loaders refuse other shapes at their line. The same bound holds for every point rays start
// from: the camera and point and spot lights (Embree asserts on a ray origin beyond ~1.8e18).
inline constexpr float kMaxSceneCoordinate = 1e12f;

// A point rays may start from: finite and within kMaxSceneCoordinate of the origin per axis.
inline bool within_scene_limits(const Vec3& p) {
    for (float c : {p.x, p.y, p.z})
        if (!(std::abs(c) <= kMaxSceneCoordinate)) return false;
    return true;
}

// Transforms rays pass through are checked by ray_transform_problem
// (core/base/ray_transform_check.h), kept out of this header, which the ray tracer's hot
// headers include.

}  // namespace render
