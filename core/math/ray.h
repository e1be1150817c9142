#pragma once

#include "core/math/constants.h"
#include "core/math/vec.h"

namespace render {

struct Ray {
    Vec3 origin;
    Vec3 direction;  // unit length
    float t_min = 0.0f;
    float t_max = kInfinity;

    Ray() = default;
    Ray(const Vec3& o, const Vec3& d, float tmin = 0.0f, float tmax = kInfinity)
        : origin(o), direction(d), t_min(tmin), t_max(tmax) {}
    Vec3 at(float t) const { return origin + direction * t; }
};

}  // namespace render
