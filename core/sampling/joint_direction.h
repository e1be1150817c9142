#pragma once

// U2 of joint path sampling (docs/design/media.md, "Joint path sampling"): the direction w from the
// first medium vertex c toward the second vertex b, chosen so that the direction carries the
// marginal of G(a, b) along the whole half-line (c, w) toward the light point a:
//     integral over t >= 0 of 1 / |a - (c + t w)|^2 = (pi - theta) / (|a - c| sin theta),
// theta being the angle between w and c -> a. Normalised over the sphere:
//     p(w) = (pi - theta) / (pi^3 sin theta),   CDF(theta) = theta (2 pi - theta) / pi^2,
// phi uniform about the axis c -> a. Sampled by inverting the CDF:
// theta = pi (1 - sqrt(1 - u1)) = pi u1 / (1 + sqrt(1 - u1)) (no cancellation for small u1).
//
// Guards: the density grows like 1 / theta at the axis (integrably); pdf_w() evaluates it at
// no angle below 1e-7 rad (the float resolution of a unit vector), a cap of probability
// ~6e-8. At theta -> pi it tends to 1 / pi^3 and is evaluated through (pi - theta) / sin theta
// computed from the same two numbers (no 0 / 0). When c and a coincide the axis is undefined;
// both sample() and pdf_w() then use +z, so they still describe one distribution.

#include <cmath>

#include "core/math/frame.h"
#include "core/math/vec.h"

namespace render {

class JointDirectionSampler {
  public:
    static constexpr double kMinAngle = 1e-7;

    // The vertex c and the light point a.
    JointDirectionSampler(const Vec3& c, const Vec3& light) {
        unit_axis(c, light, axis64_);
        axis_ = Vec3(float(axis64_[0]), float(axis64_[1]), float(axis64_[2]));
        frame_ = Frame::from_normal(axis_);
    }

    Vec3 sample(Vec2 u) const {
        float pdf;
        return sample(u, pdf);
    }

    // The same direction and its density per steradian from the angle drawn, which saves
    // evaluating pdf_w() (the angle back from the direction) for it; the two differ by what the
    // float direction resolves of its angle (joint_sampling_test).
    Vec3 sample(Vec2 u, float& pdf) const {
        const double root = std::sqrt(1.0 - double(u.x));
        const double theta = kPi64 * u.x / (1.0 + root);
        const double phi = 2.0 * kPi64 * u.y;
        const double sin_theta = std::sin(theta);
        // (pi - theta) / sin(theta) with pi - theta = pi root exactly, clamped as pdf_w() is.
        const double ratio = theta >= kMinAngle ? kPi64 * root / sin_theta
                                                : (kPi64 - kMinAngle) / std::sin(kMinAngle);
        pdf = float(ratio / (kPi64 * kPi64 * kPi64));
        const Vec3 local(float(sin_theta * std::cos(phi)), float(sin_theta * std::sin(phi)),
                         float(std::cos(theta)));
        return normalize(frame_.to_world(local));
    }

    // Density per steradian of direction w (unit).
    float pdf_w(const Vec3& w) const { return pdf_about_axis(axis64_, w); }

    // The same for the vertex c and the light point without building the sampler (its frame
    // serves sample() only): the density MIS evaluates for paths other techniques made.
    static float pdf_w(const Vec3& c, const Vec3& light, const Vec3& w) {
        double axis[3];
        unit_axis(c, light, axis);
        return pdf_about_axis(axis, w);
    }

    const Vec3& axis() const { return axis_; }

  private:
    static constexpr double kPi64 = 3.14159265358979323846;

    static void unit_axis(const Vec3& c, const Vec3& light, double* axis) {
        // In double: the density near the axis depends on the angle to it, which float
        // differences would resolve only to ~1e-7 / theta relative.
        double d[3], length2 = 0;
        for (int k = 0; k < 3; ++k) {
            d[k] = double(light[k]) - c[k];
            length2 += d[k] * d[k];
        }
        const double length = std::sqrt(length2);
        const bool defined = length > 0 && std::isfinite(length);
        for (int k = 0; k < 3; ++k) axis[k] = defined ? d[k] / length : (k == 2 ? 1.0 : 0.0);
    }

    static float pdf_about_axis(const double* a, const Vec3& w) {
        const double wx = w.x, wy = w.y, wz = w.z;
        const double c = a[0] * wx + a[1] * wy + a[2] * wz;
        const double cx = a[1] * wz - a[2] * wy, cy = a[2] * wx - a[0] * wz,
                     cz = a[0] * wy - a[1] * wx;
        const double s = std::sqrt(cx * cx + cy * cy + cz * cz);
        double ratio;  // (pi - theta) / sin(theta)
        if (c < 0) {
            const double rest = std::atan2(s, -c);  // pi - theta, accurate near pi
            ratio = s > 0 ? rest / s : 1.0;
        } else {
            const double theta = std::max(std::atan2(s, c), kMinAngle);
            ratio = (kPi64 - theta) / std::sin(theta);
        }
        return float(ratio / (kPi64 * kPi64 * kPi64));
    }

    double axis64_[3];
    Vec3 axis_;
    Frame frame_;
};

}  // namespace render
