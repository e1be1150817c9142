#include "core/scene/pbrt/transforms.h"

#include <cmath>

namespace render::pbrt {
namespace {

using M = Transform::Matrix;

M identity() {
    M m{};
    for (size_t i = 0; i < 4; ++i) m[i][i] = 1;
    return m;
}

}  // namespace

Transform matrix_from_pbrt(const std::array<double, 16>& v) {
    M m{};
    for (size_t r = 0; r < 4; ++r)
        for (size_t c = 0; c < 4; ++c) m[r][c] = v[c * 4 + r];
    return Transform(m);
}

Transform look_at(const Vec3& eye, const Vec3& look, const Vec3& up) {
    const double e[3] = {eye.x, eye.y, eye.z};
    double d[3] = {double(look.x) - eye.x, double(look.y) - eye.y, double(look.z) - eye.z};
    double u[3] = {up.x, up.y, up.z};
    auto normalize3 = [](double* a) {
        const double l = std::sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
        if (!(l > 0) || !std::isfinite(l)) return false;
        for (int i = 0; i < 3; ++i) a[i] /= l;
        return true;
    };
    auto cross3 = [](const double* a, const double* b, double* out) {
        out[0] = a[1] * b[2] - a[2] * b[1];
        out[1] = a[2] * b[0] - a[0] * b[2];
        out[2] = a[0] * b[1] - a[1] * b[0];
    };
    double right[3], new_up[3];
    if (!normalize3(d) || !normalize3(u)) return Transform(M{});
    cross3(u, d, right);
    if (!normalize3(right)) return Transform(M{});
    cross3(d, right, new_up);
    // Camera-to-world: the columns are right, up, forward and the eye; pbrt's LookAt is the
    // inverse (world-to-camera), which for an orthonormal frame is the transpose.
    M m = identity();
    for (size_t r = 0; r < 3; ++r) {
        m[0][r] = right[r];
        m[1][r] = new_up[r];
        m[2][r] = d[r];
    }
    for (size_t r = 0; r < 3; ++r) m[r][3] = -(m[r][0] * e[0] + m[r][1] * e[1] + m[r][2] * e[2]);
    return Transform(m);
}

Transform rotate(double angle_degrees, const Vec3& axis) {
    return Transform::rotate(axis, float(angle_degrees));
}

}  // namespace render::pbrt
