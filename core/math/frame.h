#pragma once

#include "core/math/vec.h"

namespace render {

// Orthonormal basis with z = n. Local coordinates put the normal on +z, so cos(theta) = w.z.
struct Frame {
    Vec3 s, t, n;

    Frame() : s(1, 0, 0), t(0, 1, 0), n(0, 0, 1) {}
    Frame(const Vec3& s_, const Vec3& t_, const Vec3& n_) : s(s_), t(t_), n(n_) {}

    // Branchless basis of Duff et al. 2017, "Building an Orthonormal Basis, Revisited".
    static Frame from_normal(const Vec3& n) {
        float sign = std::copysign(1.0f, n.z);
        float a = -1.0f / (sign + n.z);
        float b = n.x * n.y * a;
        Vec3 s(1.0f + sign * n.x * n.x * a, sign * b, -sign * n.x);
        Vec3 t(b, sign + n.y * n.y * a, -n.y);
        return Frame(s, t, n);
    }

    Vec3 to_local(const Vec3& v) const { return {dot(v, s), dot(v, t), dot(v, n)}; }
    Vec3 to_world(const Vec3& v) const { return s * v.x + t * v.y + n * v.z; }
};

// Trigonometry of a local direction (unit vector, z = normal).
inline float cos_theta(const Vec3& w) {
    return w.z;
}
inline float abs_cos_theta(const Vec3& w) {
    return std::abs(w.z);
}
inline float cos2_theta(const Vec3& w) {
    return w.z * w.z;
}
inline float sin2_theta(const Vec3& w) {
    return std::max(0.0f, 1.0f - w.z * w.z);
}
inline float tan2_theta(const Vec3& w) {
    return sin2_theta(w) / cos2_theta(w);
}
inline bool same_hemisphere(const Vec3& a, const Vec3& b) {
    return a.z * b.z > 0;
}

}  // namespace render
