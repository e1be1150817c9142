#pragma once

// U1 of joint path sampling on a half-line (docs/design/media.md, "Joint path sampling"): a
// distance t >= 0 along the ray (c, w) with density proportional to 1 / |a - (c + t w)|^2 toward
// the light point a, i.e. equi-angular sampling over the whole half-line. With t_ca = |a - c| and
// theta the angle between w and c -> a (D = t_ca sin theta, delta = t_ca cos theta), the
// half-line subtends the angle pi - theta seen from a, so
//     p(t) = D / ((pi - theta) (D^2 + (t - delta)^2)),
// and the sample at angle phi = u (pi - theta) past the ray's origin, as seen from a, is
// t = t_ca sin(phi) / sin(theta + phi) (the law of sines in the triangle c, a, c + t w).
// Together with U3 and U2 the product of the three densities is exactly
// G(a, b) / (pi^3 C) (joint_eye_distance.h). volpt uses the truncated form on [0, T_c]
// (EquiAngularSampler) instead, which is what the product of its conditionals needs; this one
// is the exact half-line conditional of the specification (tested with the product identity).
//
// Guards: theta is clamped to [1e-7, pi] in both sample() and pdf_l() (a light on the ray's
// line ahead would make the density a delta); when pi - theta < 1e-6 both use the limit
// density t_ca / (t_ca + t)^2 (CDF t / (t_ca + t), t = t_ca u / (1 - u)); t_ca is at least
// 1e-30 (the light at c). Samples too far for a float are returned as the largest float.

#include <algorithm>
#include <cmath>
#include <limits>

#include "core/math/vec.h"

namespace render {

class HalfLineEquiAngularSampler {
  public:
    static constexpr double kMinAngle = 1e-7;
    static constexpr double kLimitAngle = 1e-6;

    // Ray origin c, unit direction w, and the light point a.
    HalfLineEquiAngularSampler(const Vec3& origin, const Vec3& direction, const Vec3& light) {
        const double lx = double(light.x) - origin.x, ly = double(light.y) - origin.y,
                     lz = double(light.z) - origin.z;
        const double along = lx * direction.x + ly * direction.y + lz * direction.z;
        const double px = lx - along * direction.x, py = ly - along * direction.y,
                     pz = lz - along * direction.z;
        const double across = std::sqrt(px * px + py * py + pz * pz);
        distance_ca_ = std::max(std::sqrt(lx * lx + ly * ly + lz * lz), 1e-30);
        theta_ = std::clamp(std::atan2(across, along), kMinAngle, kPi64);
        range_ = kPi64 - theta_;
        limit_ = range_ < kLimitAngle;
        delta_ = distance_ca_ * std::cos(theta_);
        foot_distance_ = distance_ca_ * std::sin(theta_);
    }

    float sample(float u) const {
        double t;
        if (limit_) {
            t = distance_ca_ * u / (1.0 - u);
        } else {
            const double phi = u * range_;
            const double s = std::sin(theta_ + phi);
            t = s > 0 ? distance_ca_ * std::sin(phi) / s : std::numeric_limits<double>::infinity();
        }
        return float(std::clamp(t, 0.0, double(std::numeric_limits<float>::max())));
    }

    // Density per unit length at t (zero for t < 0).
    float pdf_l(float t) const {
        if (!(t >= 0)) return 0.0f;
        if (limit_) {
            const double r = distance_ca_ + t;
            return float(distance_ca_ / (r * r));
        }
        const double x = t - delta_;
        return float(foot_distance_ / (range_ * (foot_distance_ * foot_distance_ + x * x)));
    }

  private:
    static constexpr double kPi64 = 3.14159265358979323846;
    double distance_ca_ = 0, theta_ = 0, range_ = 0, delta_ = 0, foot_distance_ = 0;
    bool limit_ = false;
};

}  // namespace render
