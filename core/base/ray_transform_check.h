#pragma once

// Transforms rays pass through: shapes', instances' and media grids' to_world (Embree carries a
// world ray into an instance's space with the inverse, the analytic shapes and the grids do the
// same), and the camera's and the lights' to_world (rays start from them). A near-singular
// transform turns a valid world ray into a non-finite or huge one in the shape's space, which
// Embree asserts on, and a camera or light under one emits degenerate rays. The loaders refuse
// such a transform at its line (docs/guide/reliability.md, "Transforms rays pass through").

#include <string>

namespace render {

class Transform;

// The precision bound: ||A||_F ||A^-1||_F of the 3x3 linear part A. Mirrors, rotations and
// uniform scales give 3; a box flattened 1000:1 about 1.4e3. Beyond 1e6 a float ray keeps about
// four of its 24 bits in the shape's space.
inline constexpr double kMaxTransformCondition = 1e6;
// Embree's bound on a ray's origin and direction per axis is FLT_LARGE (1.844e18, its
// RayK::valid()); with a margin, every point within kMaxSceneCoordinate must map within this.
inline constexpr double kMaxObjectSpaceCoordinate = 1e18;

// Why rays cannot pass through `t` (empty when they can): a non-finite entry, a singular or
// near-singular linear part, or an inverse that maps a point within the scene limits
// (core/base/scene_limits.h) beyond what Embree accepts.
std::string ray_transform_problem(const Transform& t);

}  // namespace render
