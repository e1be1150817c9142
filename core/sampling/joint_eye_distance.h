#pragma once

// U3 of joint path sampling (Georgiev, Krivanek, Hachisuka, Nowrouzezahrai, Jarosz 2013;
// docs/design/media.md, "Joint path sampling"): the distance t of the first medium vertex c on an
// eye ray, chosen before the second vertex b and the light point a are connected, with density
// proportional to 1 / |a - c(t)|. That is the marginal over b of G(a, b) G(b, c) in an
// isotropic medium (the integral over all b of 1 / (|a - b|^2 |b - c|^2) is pi^3 / |a - c|), so
// together with U2 (joint_direction.h) and U1 (equi-angular toward a) the product of the three
// densities is G(a, b) / (pi^3 C) and the double-scattering estimator has no geometric
// singularity left.
//
// With delta the ray distance of the foot of the perpendicular from a and D the distance of a
// from the ray's line, on the range [t0, t1]:
//     p(t) = 1 / (C sqrt(D^2 + (t - delta)^2)),  C = asinh((t1 - delta) / D) - asinh((t0 - delta) /
//     D).
// The range must be finite (the integral of 1 / distance over a half-line diverges).
//
// Precision, as in EquiAngularSampler: everything in double relative to t0. asinh(x / D) is
// ln((x + r) / D) with r = sqrt(D^2 + x^2), and x + r is computed as D^2 / (r - x) when x < 0
// (no cancellation when the light is far along the line), so C = ln(g1 / g0) with
// g_i = x_i + r_i. The inverse, t = t0 + r0 sinh(s) + x0 (cosh(s) - 1) with s = u C, is
// rearranged for x0 < 0 so that no two large terms cancel (see sample()).
// Guards: D is clamped to 1e-6 of the problem's size (a light on the line makes the density a
// spike of width D); sample() and pdf_l() use the same clamp. A degenerate range (C not
// positive and finite) falls back to uniform distances.

#include <algorithm>
#include <cmath>

#include "core/math/vec.h"
#include "core/sampling/ray_point_geometry.h"

namespace render {

class JointEyeDistanceSampler {
  public:
    // Ray origin and unit direction, the light point, and the distance range [t0, t1]
    // (finite, t0 < t1).
    JointEyeDistanceSampler(const Vec3& origin, const Vec3& direction, const Vec3& light, float t0,
                            float t1)
        : JointEyeDistanceSampler(ray_point_geometry(origin, direction, light, t0, t1), t0, t1) {}

    // The same density with delta and D given directly (joint_light_distance.h: the distance
    // from a point of one line to another line has this form).
    JointEyeDistanceSampler(const RayPointGeometry& g, float t0, float t1) : t0_(t0), t1_(t1) {
        delta_ = g.delta;
        distance_ = g.distance;
        x0_ = t0 - delta_;
        r0_ = std::hypot(distance_, x0_);
        const double x1 = t1 - delta_;
        log_range_ = std::log(plus_root(x1, std::hypot(distance_, x1)) / plus_root(x0_, r0_));
        uniform_ = !(log_range_ > 0 && std::isfinite(log_range_));
    }

    float sample(float u) const {
        if (uniform_) return std::clamp(t0_ + u * (t1_ - t0_), t0_, t1_);
        // t - t0 = D sinh(asinh(x0 / D) + s) - x0 = r0 sinh(s) + x0 (cosh(s) - 1): the
        // second term is negative for x0 < 0, where r0 + x0 = D^2 / (r0 - x0) is small; so
        // write it as (r0 + x0) sinh(s) - x0 (1 - e^-s) (each term >= 0 when x0 <= 0).
        const double s = u * log_range_;
        const double dt = x0_ <= 0 ? plus_root(x0_, r0_) * std::sinh(s) - x0_ * -std::expm1(-s)
                                   : r0_ * std::sinh(s) + x0_ * (std::cosh(s) - 1.0);
        return std::clamp(float(t0_ + dt), t0_, t1_);
    }

    // Density per unit length at t (zero outside [t0, t1]).
    float pdf_l(float t) const {
        if (!(t >= t0_ && t <= t1_)) return 0.0f;
        if (uniform_) return 1.0f / (t1_ - t0_);
        return float(1.0 / (log_range_ * std::hypot(distance_, double(t) - delta_)));
    }

    // The normalisation C (for the product identity; 0 when uniform).
    double log_range() const { return uniform_ ? 0.0 : log_range_; }

  private:
    // x + r, r = sqrt(D^2 + x^2) given, without cancellation.
    double plus_root(double x, double r) const {
        return x >= 0 ? x + r : distance_ * distance_ / (r - x);
    }

    float t0_, t1_;
    double delta_ = 0, distance_ = 0, x0_ = 0, r0_ = 0, log_range_ = 0;
    bool uniform_ = false;
};

}  // namespace render
