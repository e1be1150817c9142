#pragma once

// Warps from the unit square to sampling domains, each beside its density. Densities are
// with respect to the domain's natural measure: solid angle for directions, area for
// points. Every pair is checked by a chi-square test in tests/unit/sampling/warp_test.cpp.

#include <algorithm>
#include <cmath>

#include "core/math/constants.h"
#include "core/math/vec.h"

namespace render::warp {

inline float safe_sqrt(float x) {
    return std::sqrt(std::max(0.0f, x));
}

// Concentric map of Shirley and Chiu: square -> unit disk, area preserving up to pi.
inline Vec2 square_to_uniform_disk_concentric(Vec2 u) {
    float a = 2.0f * u.x - 1.0f, b = 2.0f * u.y - 1.0f;
    if (a == 0 && b == 0) return {0, 0};
    float r, phi;
    if (std::abs(a) > std::abs(b)) {
        r = a;
        phi = (kPi / 4.0f) * (b / a);
    } else {
        r = b;
        phi = (kPi / 2.0f) - (kPi / 4.0f) * (a / b);
    }
    return {r * std::cos(phi), r * std::sin(phi)};
}
inline float square_to_uniform_disk_pdf(Vec2 p) {
    return p.x * p.x + p.y * p.y <= 1.0f ? kInvPi : 0.0f;
}

inline Vec3 square_to_uniform_sphere(Vec2 u) {
    float z = 1.0f - 2.0f * u.x;
    float r = safe_sqrt(1.0f - z * z);
    float phi = 2.0f * kPi * u.y;
    return {r * std::cos(phi), r * std::sin(phi), z};
}
inline float square_to_uniform_sphere_pdf() {
    return kInv4Pi;
}

inline Vec3 square_to_uniform_hemisphere(Vec2 u) {
    float z = u.x;
    float r = safe_sqrt(1.0f - z * z);
    float phi = 2.0f * kPi * u.y;
    return {r * std::cos(phi), r * std::sin(phi), z};
}
inline float square_to_uniform_hemisphere_pdf(const Vec3& w) {
    return w.z > 0 ? kInv2Pi : 0.0f;
}

// Malley's method: cosine-weighted hemisphere via the concentric disk.
inline Vec3 square_to_cosine_hemisphere(Vec2 u) {
    Vec2 d = square_to_uniform_disk_concentric(u);
    float z = safe_sqrt(1.0f - d.x * d.x - d.y * d.y);
    return {d.x, d.y, z};
}
inline float square_to_cosine_hemisphere_pdf(const Vec3& w) {
    return w.z > 0 ? w.z * kInvPi : 0.0f;
}

// Uniform directions in the cone around +z with half-angle acos(cos_max). This is also the
// uniform spherical-cap sampler used for spheres seen from outside.
inline Vec3 square_to_uniform_cone(Vec2 u, float cos_max) {
    float z = 1.0f - u.x * (1.0f - cos_max);
    float r = safe_sqrt(1.0f - z * z);
    float phi = 2.0f * kPi * u.y;
    return {r * std::cos(phi), r * std::sin(phi), z};
}
inline float square_to_uniform_cone_pdf(const Vec3& w, float cos_max) {
    if (w.z < cos_max) return 0.0f;
    return 1.0f / (2.0f * kPi * (1.0f - cos_max));
}

// Barycentrics (b1, b2) uniform on a triangle; b0 = 1 - b1 - b2. Area pdf is 1 / area.
// Uses the square-root parameterisation; pdf over the barycentric triangle is 2.
inline Vec2 square_to_uniform_triangle(Vec2 u) {
    float s = safe_sqrt(u.x);
    return {1.0f - s, u.y * s};
}
inline float square_to_uniform_triangle_pdf(Vec2 b) {
    return (b.x >= 0 && b.y >= 0 && b.x + b.y <= 1) ? 2.0f : 0.0f;
}

// Directions around +z with density proportional to cos^n (the normalised Phong lobe).
// pdf = (n + 1) / (2 pi) * cos^n(theta) on the hemisphere around the lobe axis.
inline Vec3 square_to_phong_lobe(Vec2 u, float exponent) {
    float z = std::pow(u.x, 1.0f / (exponent + 1.0f));
    float r = safe_sqrt(1.0f - z * z);
    float phi = 2.0f * kPi * u.y;
    return {r * std::cos(phi), r * std::sin(phi), z};
}
inline float square_to_phong_lobe_pdf(const Vec3& w, float exponent) {
    if (w.z <= 0) return 0.0f;
    return (exponent + 1.0f) * kInv2Pi * std::pow(w.z, exponent);
}

}  // namespace render::warp
