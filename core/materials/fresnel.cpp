#include "core/materials/fresnel.h"

#include <algorithm>
#include <cmath>

namespace render {

DielectricFresnel fresnel_dielectric(float cos_theta_i, float eta) {
    DielectricFresnel result;
    const bool outside = cos_theta_i >= 0;
    result.eta_it = outside ? eta : 1.0f / eta;
    result.eta_ti = outside ? 1.0f / eta : eta;

    // Snell's law in the form cos^2 t = 1 - (n_i / n_t)^2 sin^2 i.
    const float cos_i = std::abs(cos_theta_i);
    const float cos_t_sqr = 1.0f - result.eta_ti * result.eta_ti * (1.0f - cos_i * cos_i);
    if (cos_t_sqr <= 0) {  // total internal reflection
        result.reflectance = 1;
        result.cos_theta_t = 0;
        return result;
    }
    const float cos_t = std::sqrt(cos_t_sqr);
    result.cos_theta_t = outside ? -cos_t : cos_t;
    if (eta == 1) {
        result.reflectance = 0;
        return result;
    }
    if (cos_i == 0) {  // grazing: everything reflects
        result.reflectance = 1;
        return result;
    }
    // Amplitude coefficients for s- and p-polarised light.
    const float r_s = (cos_i - result.eta_it * cos_t) / (cos_i + result.eta_it * cos_t);
    const float r_p = (result.eta_it * cos_i - cos_t) / (result.eta_it * cos_i + cos_t);
    result.reflectance = std::min(1.0f, 0.5f * (r_s * r_s + r_p * r_p));
    return result;
}

float fresnel_conductor(float cos_theta_i, float eta, float k) {
    // Exact unpolarised reflectance for a complex IOR (e.g. Born & Wolf; pbrt-v3's form with
    // a^2 + b^2 computed once).
    const float cos_i = std::clamp(cos_theta_i, 0.0f, 1.0f);
    const float cos_i2 = cos_i * cos_i;
    const float sin_i2 = 1.0f - cos_i2;
    const float sin_i4 = sin_i2 * sin_i2;

    const float t0 = eta * eta - k * k - sin_i2;
    const float a2_plus_b2 = std::sqrt(std::max(0.0f, t0 * t0 + 4.0f * eta * eta * k * k));
    const float a = std::sqrt(std::max(0.0f, 0.5f * (a2_plus_b2 + t0)));

    const float t1 = a2_plus_b2 + cos_i2;
    const float t2 = 2.0f * cos_i * a;
    if (t1 + t2 <= 0) return 1.0f;  // grazing on an index-matched conductor
    const float r_s = (t1 - t2) / (t1 + t2);

    const float t3 = a2_plus_b2 * cos_i2 + sin_i4;
    const float t4 = t2 * sin_i2;
    const float r_p = t3 + t4 > 0 ? r_s * (t3 - t4) / (t3 + t4) : r_s;
    return std::clamp(0.5f * (r_s + r_p), 0.0f, 1.0f);
}

Rgb fresnel_conductor(float cos_theta_i, const Rgb& eta, const Rgb& k) {
    return {fresnel_conductor(cos_theta_i, eta.r, k.r), fresnel_conductor(cos_theta_i, eta.g, k.g),
            fresnel_conductor(cos_theta_i, eta.b, k.b)};
}

float fresnel_diffuse_reflectance(float eta) {
    // Composite Simpson in mu = cos(theta). The integrand has a kink at the critical angle
    // when eta < 1; 4096 intervals put the error far below float precision anyway.
    constexpr int n = 4096;
    double sum = 0;
    for (int i = 0; i <= n; ++i) {
        const double mu = double(i) / n;
        const double weight = (i == 0 || i == n) ? 1 : (i % 2 ? 4 : 2);
        sum += weight * fresnel_dielectric(float(mu), eta).reflectance * mu;
    }
    return float(2.0 * sum / (3.0 * n));
}

}  // namespace render
