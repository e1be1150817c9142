#include "core/math/transform.h"

#include <cmath>

namespace render {
namespace {

using Matrix = Transform::Matrix;

Matrix identity() {
    Matrix m{};
    for (int i = 0; i < 4; ++i) m[i][i] = 1.0;
    return m;
}

Matrix multiply(const Matrix& a, const Matrix& b) {
    Matrix r{};
    for (int i = 0; i < 4; ++i)
        for (int j = 0; j < 4; ++j)
            for (int k = 0; k < 4; ++k) r[i][j] += a[i][k] * b[k][j];
    return r;
}

// Gauss-Jordan elimination with partial pivoting. Returns false for a singular matrix.
bool invert(const Matrix& m, Matrix& inv) {
    Matrix a = m;
    inv = identity();
    for (int col = 0; col < 4; ++col) {
        int pivot = col;
        for (int row = col + 1; row < 4; ++row)
            if (std::abs(a[row][col]) > std::abs(a[pivot][col])) pivot = row;
        if (std::abs(a[pivot][col]) < 1e-300) return false;
        std::swap(a[col], a[pivot]);
        std::swap(inv[col], inv[pivot]);
        double scale = 1.0 / a[col][col];
        for (int j = 0; j < 4; ++j) {
            a[col][j] *= scale;
            inv[col][j] *= scale;
        }
        for (int row = 0; row < 4; ++row) {
            if (row == col) continue;
            double f = a[row][col];
            if (f == 0.0) continue;
            for (int j = 0; j < 4; ++j) {
                a[row][j] -= f * a[col][j];
                inv[row][j] -= f * inv[col][j];
            }
        }
    }
    return true;
}

}  // namespace

Transform::Transform() : m_(identity()), inv_(identity()) {}

Transform::Transform(const Matrix& m) : m_(m) {
    singular_ = !invert(m, inv_);
    if (singular_) inv_ = Matrix{};
}

Transform Transform::translate(const Vec3& d) {
    Matrix m = identity();
    m[0][3] = d.x;
    m[1][3] = d.y;
    m[2][3] = d.z;
    return Transform(m);
}

Transform Transform::scale(const Vec3& s) {
    Matrix m = identity();
    m[0][0] = s.x;
    m[1][1] = s.y;
    m[2][2] = s.z;
    return Transform(m);
}

Transform Transform::rotate(const Vec3& axis_in, float angle_degrees) {
    double len = std::sqrt(double(axis_in.x) * axis_in.x + double(axis_in.y) * axis_in.y +
                           double(axis_in.z) * axis_in.z);
    double x = axis_in.x / len, y = axis_in.y / len, z = axis_in.z / len;
    double theta = angle_degrees * M_PI / 180.0;
    double s = std::sin(theta), c = std::cos(theta), t = 1.0 - c;
    Matrix m = identity();
    m[0][0] = t * x * x + c;
    m[0][1] = t * x * y - s * z;
    m[0][2] = t * x * z + s * y;
    m[1][0] = t * x * y + s * z;
    m[1][1] = t * y * y + c;
    m[1][2] = t * y * z - s * x;
    m[2][0] = t * x * z - s * y;
    m[2][1] = t * y * z + s * x;
    m[2][2] = t * z * z + c;
    return Transform(m);
}

Transform Transform::look_at(const Vec3& origin, const Vec3& target, const Vec3& up) {
    Vec3 dir = normalize(target - origin);
    Vec3 left = normalize(cross(normalize(up), dir));
    Vec3 new_up = cross(dir, left);
    Matrix m = identity();
    for (int i = 0; i < 3; ++i) {
        m[i][0] = left[i];
        m[i][1] = new_up[i];
        m[i][2] = dir[i];
        m[i][3] = origin[i];
    }
    return Transform(m);
}

Transform Transform::operator*(const Transform& other) const {
    return Transform(multiply(m_, other.m_), multiply(other.inv_, inv_),
                     singular_ || other.singular_);
}

Transform Transform::inverse() const {
    return Transform(inv_, m_, singular_);
}

Vec3 Transform::apply_point(const Vec3& p) const {
    double r[4];
    for (int i = 0; i < 4; ++i) r[i] = m_[i][0] * p.x + m_[i][1] * p.y + m_[i][2] * p.z + m_[i][3];
    if (r[3] != 1.0 && r[3] != 0.0) {
        double w = 1.0 / r[3];
        return Vec3(float(r[0] * w), float(r[1] * w), float(r[2] * w));
    }
    return Vec3(float(r[0]), float(r[1]), float(r[2]));
}

Vec3 Transform::apply_vector(const Vec3& v) const {
    return Vec3(float(m_[0][0] * v.x + m_[0][1] * v.y + m_[0][2] * v.z),
                float(m_[1][0] * v.x + m_[1][1] * v.y + m_[1][2] * v.z),
                float(m_[2][0] * v.x + m_[2][1] * v.y + m_[2][2] * v.z));
}

Vec3 Transform::apply_normal(const Vec3& n) const {
    // (M^-1)^T n
    return Vec3(float(inv_[0][0] * n.x + inv_[1][0] * n.y + inv_[2][0] * n.z),
                float(inv_[0][1] * n.x + inv_[1][1] * n.y + inv_[2][1] * n.z),
                float(inv_[0][2] * n.x + inv_[1][2] * n.y + inv_[2][2] * n.z));
}

double Transform::determinant3x3() const {
    const Matrix& m = m_;
    return m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) -
           m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0]) +
           m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
}

}  // namespace render
