#pragma once

// B2 of joint path sampling (Georgiev, Krivanek, Hachisuka, Nowrouzezahrai, Jarosz 2013;
// docs/design/media.md, "J2: segment-segment connections"): the distance t of the light-side medium
// vertex b on a light ray (o, w), chosen before the eye-side vertex c is sampled on the eye
// half-line (e, u) by equi-angular sampling toward b (B1, half_line_equiangular.h).
//
// The ideal B2 density is the marginal of B1's target over c: the integral over the eye
// half-line of 1 / |b - c|^2, which is (pi - theta_b) / h(b) (h: the distance of b from the eye
// line, theta_b: the angle between u and e -> b). The specification tabulates it; we sample
// its singular part exactly instead: h(b(t)) = sin(alpha) sqrt(D^2 + (t - t_perp)^2), with
// alpha the angle between the two lines, t_perp the light-ray distance of their closest
// approach and D = h_perp / sin(alpha), so
//     p(t) = 1 / (C sqrt(D^2 + (t - t_perp)^2)),  t in [0, T],
// the U3 form (joint_eye_distance.h) with delta = t_perp. The factor pi - theta_b in [0, pi]
// that this leaves out is bounded, so the ratio of the ideal density to this one is bounded
// (by pi C / sin(alpha)): exact, normalised, with full support on [0, T]. With B1 the product is
//     p_B2(t) p_B1(s | b) = G(b, c) sin(alpha) / (C (pi - theta_b)),
// checked numerically by joint_sampling_test. T must be finite (the integral of 1 / h over a
// half-line diverges): bpt uses the light ray's exit from the scene's bounding sphere, which
// every technique can compute without tracing (light_ray_range, core/integrators/joint_segment.h).
//
// Guards: (nearly) parallel lines (sin^2 alpha < 1e-12) have a constant h, and the density is
// uniform; D is clamped to 1e-6 of the problem's size (lines that meet), as U3 clamps it; a
// degenerate range falls back to uniform distances (JointEyeDistanceSampler).

#include <algorithm>
#include <cmath>

#include "core/math/vec.h"
#include "core/sampling/joint_eye_distance.h"
#include "core/sampling/ray_point_geometry.h"

namespace render {

// Where the light ray's closest approach to the eye line lies: t_perp and D (RayPointGeometry's
// delta and distance in the U3 form), or parallel lines.
struct LineLineGeometry {
    RayPointGeometry foot;
    bool parallel = false;
    double sin_alpha = 0;
};

inline LineLineGeometry line_line_geometry(const Vec3& light_origin, const Vec3& light_direction,
                                           const Vec3& eye_origin, const Vec3& eye_direction,
                                           float t1) {
    const double w[3] = {double(light_origin.x) - eye_origin.x,
                         double(light_origin.y) - eye_origin.y,
                         double(light_origin.z) - eye_origin.z};
    const double l[3] = {light_direction.x, light_direction.y, light_direction.z};
    const double u[3] = {eye_direction.x, eye_direction.y, eye_direction.z};
    auto cross = [](const double* a, const double* b, double* out) {
        out[0] = a[1] * b[2] - a[2] * b[1];
        out[1] = a[2] * b[0] - a[0] * b[2];
        out[2] = a[0] * b[1] - a[1] * b[0];
    };
    auto dot = [](const double* a, const double* b) {
        return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    };
    double wu[3], lu[3];
    cross(w, u, wu);  // (b(t) - e) x u = wu + t lu: |.| is the distance of b(t) from the eye line
    cross(l, u, lu);
    const double sin2 = dot(lu, lu);
    LineLineGeometry g;
    g.sin_alpha = std::sqrt(sin2);
    if (!(sin2 >= 1e-12)) {
        g.parallel = true;
        return g;
    }
    g.foot.delta = -dot(wu, lu) / sin2;
    const double h2 = std::max(dot(wu, wu) - dot(wu, lu) * dot(wu, lu) / sin2, 0.0);
    const double scale = std::max({double(t1), std::abs(g.foot.delta), 1e-30});
    g.foot.distance = std::max(std::sqrt(h2 / sin2), 1e-6 * scale);
    return g;
}

class JointLightDistanceSampler {
  public:
    // The light ray (origin, unit direction), the eye ray (origin, unit direction) and the
    // light ray's range [0, t1] (finite, positive).
    JointLightDistanceSampler(const Vec3& light_origin, const Vec3& light_direction,
                              const Vec3& eye_origin, const Vec3& eye_direction, float t1)
        : JointLightDistanceSampler(
              line_line_geometry(light_origin, light_direction, eye_origin, eye_direction, t1),
              t1) {}

    float sample(float u) const {
        if (geometry_.parallel) return std::clamp(u * t1_, 0.0f, t1_);
        return eye_form_.sample(u);
    }

    // Density per unit length at t (zero outside [0, t1]).
    float pdf_l(float t) const {
        if (geometry_.parallel) return t >= 0 && t <= t1_ ? 1.0f / t1_ : 0.0f;
        return eye_form_.pdf_l(t);
    }

    const LineLineGeometry& geometry() const { return geometry_; }
    // The normalisation C (0 where the density is uniform).
    double log_range() const { return geometry_.parallel ? 0.0 : eye_form_.log_range(); }

  private:
    JointLightDistanceSampler(const LineLineGeometry& g, float t1)
        : geometry_(g), t1_(t1), eye_form_(g.foot, 0.0f, t1) {}

    LineLineGeometry geometry_;
    float t1_;
    JointEyeDistanceSampler eye_form_;
};

}  // namespace render
