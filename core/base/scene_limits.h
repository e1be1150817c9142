#pragma once

// The limits of what a scene may describe, in one place (the loaders, the lights and the scene
// check against these).

#include <cmath>
#include <cstdio>
#include <string>

#include "core/math/transform.h"
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

// Transforms rays pass through (shapes', instances' and media grids' to_world: Embree carries a
// world ray into an instance's space with the inverse, the analytic shapes and the grids do the
// same). A near-singular transform turns a valid world ray into a non-finite or huge one in the
// shape's space, which Embree asserts on. The loaders refuse such a transform at its line
// (docs/guide/reliability.md, "Resource limits").
//
// The precision bound: ||A||_F ||A^-1||_F of the 3x3 linear part A. Mirrors, rotations and
// uniform scales give 3; a box flattened 1000:1 about 1.4e3. Beyond 1e6 a float ray keeps about
// four of its 24 bits in the shape's space.
inline constexpr double kMaxTransformCondition = 1e6;
// Embree's bound on a ray's origin and direction per axis is FLT_LARGE (1.844e18, its
// RayK::valid()); with a margin, every point within kMaxSceneCoordinate must map within this.
inline constexpr double kMaxObjectSpaceCoordinate = 1e18;

// Why rays cannot pass through `t` (empty when they can): a non-finite entry, a singular or
// near-singular linear part, or an inverse that maps a point within the scene limits beyond
// what Embree accepts.
inline std::string ray_transform_problem(const Transform& t) {
    auto number = [](double x) {
        char buf[32];
        std::snprintf(buf, sizeof buf, "%.3g", x);
        return std::string(buf);
    };
    for (const auto& row : t.matrix())
        for (double x : row)
            if (!std::isfinite(x)) return "the transform is not finite";
    const double det = t.determinant3x3();
    if (t.is_singular() || det == 0 || !std::isfinite(det))
        return "the transform is singular (determinant " + number(det) + ")";
    const Transform::Matrix& m = t.matrix();
    const Transform inverse = t.inverse();
    const Transform::Matrix& inv = inverse.matrix();
    double norm2 = 0, inv_norm2 = 0, reach = 0;
    for (int i = 0; i < 3; ++i) {
        double row = std::abs(inv[i][3]);  // where a point within the limits can land, axis i
        for (int j = 0; j < 3; ++j) {
            norm2 += m[i][j] * m[i][j];
            inv_norm2 += inv[i][j] * inv[i][j];
            row += std::abs(inv[i][j]) * double(kMaxSceneCoordinate);
        }
        reach = std::max(reach, row);
    }
    const double condition = std::sqrt(norm2) * std::sqrt(inv_norm2);
    if (!(condition <= kMaxTransformCondition))
        return "the transform is near-singular (determinant " + number(det) +
               ", condition number " + number(condition) + ", at most " +
               number(kMaxTransformCondition) + " is accepted)";
    if (!(reach <= kMaxObjectSpaceCoordinate))
        return "the transform shrinks too much: a point within the scene limits (" +
               number(kMaxSceneCoordinate) + " from the origin) would be " + number(reach) +
               " from the shape's origin in its own space, beyond what the ray tracer accepts (" +
               number(kMaxObjectSpaceCoordinate) + ")";
    return {};
}

}  // namespace render
