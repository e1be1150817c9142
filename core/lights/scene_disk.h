#pragma once

// The disk that directional and infinite lights emit from (SmallVCM's convention): a disk of
// the scene's bounding radius R, perpendicular to the emitted direction d, centred at
// center - d * R, so that every emitted ray starts outside the scene and crosses all of it.
// Its area density 1 / (pi R^2) is the positional part of those lights' emission pdfs.

#include <cmath>

#include "core/lights/light.h"
#include "core/math/constants.h"
#include "core/math/frame.h"
#include "core/sampling/warp.h"

namespace render::scene_disk {

// The bounding radius, or 1 for an empty or degenerate scene (keeps every pdf finite).
inline float radius(const SceneSphere& sphere) {
    return (sphere.radius > 0 && std::isfinite(sphere.radius)) ? sphere.radius : 1.0f;
}

inline float pdf_area(const SceneSphere& sphere) {
    float r = radius(sphere);
    return 1.0f / (kPi * r * r);
}

inline float area(const SceneSphere& sphere) {
    float r = radius(sphere);
    return kPi * r * r;
}

// Origin of a ray travelling along the unit vector `direction`, uniform on the disk.
inline Vec3 sample_origin(const SceneSphere& sphere, const Vec3& direction, Vec2 u) {
    Vec2 d = warp::square_to_uniform_disk_concentric(u);
    Frame frame = Frame::from_normal(direction);
    return sphere.center + (frame.s * d.x + frame.t * d.y - direction) * radius(sphere);
}

}  // namespace render::scene_disk
