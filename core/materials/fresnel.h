#pragma once

// Fresnel reflectance of smooth interfaces and the direction helpers that go with it. All
// directions are local (z = normal) and point away from the surface.

#include "core/math/vec.h"

namespace render {

// Reflection at a dielectric interface, as seen from a direction with cosine `cos_theta_i`
// (signed: negative means the direction is inside, below the surface).
struct DielectricFresnel {
    float reflectance = 1;  // unpolarised; 1 under total internal reflection
    float cos_theta_t = 0;  // signed cosine of the refracted direction (opposite sign of cos_i)
    float eta_it = 1;       // relative IOR n_transmitted / n_incident
    float eta_ti = 1;       // its reciprocal
};

// `eta` = n_inside / n_outside (inside = below the surface, -z).
DielectricFresnel fresnel_dielectric(float cos_theta_i, float eta);

// Reflection at a conductor with complex relative IOR eta + i k, for cos_theta_i in [0, 1].
float fresnel_conductor(float cos_theta_i, float eta, float k);
Rgb fresnel_conductor(float cos_theta_i, const Rgb& eta, const Rgb& k);

// Hemispherical average of the dielectric reflectance for cosine-distributed light arriving
// from the side where n_transmitted / n_incident = eta: 2 * integral_0^1 F(mu) mu dmu.
// Integrated numerically (as Mitsuba 0.6's non-fast path), not fitted.
float fresnel_diffuse_reflectance(float eta);

// Mirror of w about the normal z.
inline Vec3 reflect_z(const Vec3& w) {
    return {-w.x, -w.y, w.z};
}

// Refraction of w through the surface with micro-normal m, given the signed cosine of the
// refracted direction and eta_ti from fresnel_dielectric(dot(w, m), eta).
inline Vec3 refract(const Vec3& w, const Vec3& m, float cos_theta_t, float eta_ti) {
    return m * (dot(w, m) * eta_ti + cos_theta_t) - w * eta_ti;
}
inline Vec3 refract_z(const Vec3& w, float cos_theta_t, float eta_ti) {
    return {-eta_ti * w.x, -eta_ti * w.y, cos_theta_t};
}

}  // namespace render
