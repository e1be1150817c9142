#pragma once

// pbrt-v4's transform directives as matrices. pbrt post-multiplies the current transform
// (CTM = CTM * M) and writes `Transform`/`ConcatTransform` matrices column by column (the
// translation is the 13th to 15th number).

#include <array>

#include "core/math/transform.h"

namespace render::pbrt {

// The 16 numbers of `Transform [...]` as a transform (pbrt transposes what it reads).
Transform matrix_from_pbrt(const std::array<double, 16>& m);
// pbrt's LookAt: the world-to-camera transform of a camera at `eye` looking at `look`. Camera
// space is left-handed: +z forward, +y up, +x = cross(up, forward) (the image's right in pbrt).
// Singular (zero) when up is parallel to the view direction or eye == look.
Transform look_at(const Vec3& eye, const Vec3& look, const Vec3& up);
// pbrt's Rotate: angle in degrees about an axis (right-handed).
Transform rotate(double angle_degrees, const Vec3& axis);

}  // namespace render::pbrt
