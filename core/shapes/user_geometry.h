#pragma once

// Analytic shapes as Embree user geometry: one primitive whose bounds come from
// Shape::bounds() and whose ray test is the shape's nearest_hit(); the surface details are
// filled in later by fill_interaction(), so Embree's hit normal and (u, v) are not used.

#include <optional>

#include "core/base/shape.h"

namespace render {

class AnalyticShape : public Shape {
  public:
    // Nearest ray parameter t in (t_min, t_max) where org + t dir meets the surface.
    virtual std::optional<double> nearest_hit(const float org[3], const float dir[3], float t_min,
                                              float t_max) const = 0;

    unsigned attach(RTCDevice device, RTCScene scene) const final;
};

}  // namespace render
