#pragma once

// Equi-angular sampling (Kulla and Fajardo 2012, "Importance Sampling Techniques for Path
// Tracing in Participating Media"): a distance t in [t0, t1] along a ray whose density is
// proportional to 1 / (D^2 + (t - delta)^2), the inverse squared distance to a point light at
// perpendicular distance D from the ray, delta being the ray distance of the foot of that
// perpendicular. It cancels the 1/r^2 of single scattering from a point, which distance
// sampling cannot.
//
// Guards: a light (almost) on the ray's line makes D -> 0 and the density a spike, so D is
// clamped to a small fraction of the problem's size; sample() and pdf_l() apply the same clamp, so
// they always describe the same distribution.
//
// Precision: the angles atan((t - delta) / D) crowd together near +-pi/2 when the light is
// (nearly) on the line outside the range or far away along it, where floats of theta are
// ~1e-7 apart and tan(theta) turns a one-ulp step into a large step in t (samples then fall on
// a handful of distances that pdf_l() does not describe). So everything is computed in double
// and relative to t0: the angle range is Delta = atan2(D (t1 - t0), D^2 + a0 a1) with
// a_i = t_i - delta (no difference of nearly equal angles), and a sample at angle phi past
// theta0 is t0 + sin(phi) (D^2 + a0^2) / (D cos(phi) - a0 sin(phi)) (tangent addition; the
// denominator is r cos(theta0 + phi) > 0). Only a degenerate range (Delta not positive and
// finite) falls back to uniform distances.

#include <algorithm>
#include <cmath>

#include "core/math/vec.h"
#include "core/sampling/ray_point_geometry.h"

namespace render {

class EquiAngularSampler {
  public:
    // Ray origin and unit direction, the light point, and the distance range [t0, t1]
    // (finite, t0 < t1).
    EquiAngularSampler(const Vec3& origin, const Vec3& direction, const Vec3& light, float t0,
                       float t1)
        : t0_(t0), t1_(t1) {
        const RayPointGeometry g = ray_point_geometry(origin, direction, light, t0, t1);
        delta_ = g.delta;
        distance_ = g.distance;
        a0_ = t0 - delta_;
        const double a1 = t1 - delta_;
        dtheta_ = std::atan2(distance_ * (double(t1) - t0), distance_ * distance_ + a0_ * a1);
        uniform_ = !(dtheta_ > 0 && std::isfinite(dtheta_) &&
                     std::isfinite(distance_ * distance_ + a0_ * a0_));
    }

    float sample(float u) const {
        if (uniform_) return std::clamp(t0_ + u * (t1_ - t0_), t0_, t1_);
        const double phi = u * dtheta_, s = std::sin(phi), c = std::cos(phi);
        const double den = distance_ * c - a0_ * s;
        const double t =
            den > 0 ? t0_ + s * (distance_ * distance_ + a0_ * a0_) / den : double(t1_);
        return std::clamp(float(t), t0_, t1_);
    }

    // Density per unit length at t (zero outside [t0, t1]).
    float pdf_l(float t) const {
        if (!(t >= t0_ && t <= t1_)) return 0.0f;
        if (uniform_) return 1.0f / (t1_ - t0_);
        const double x = t - delta_;
        return float(distance_ / (dtheta_ * (distance_ * distance_ + x * x)));
    }

  private:
    float t0_, t1_;
    double delta_ = 0, distance_ = 0, a0_ = 0, dtheta_ = 0;
    bool uniform_ = false;
};

}  // namespace render
