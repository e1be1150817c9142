#pragma once

#include <array>

#include "core/math/vec.h"

namespace render {

// Affine/projective 4x4 transform, stored in double so that long chains of scene-file
// transforms and their inverse stay accurate; applied to float geometry.
class Transform {
  public:
    using Matrix = std::array<std::array<double, 4>, 4>;

    Transform();                          // identity
    explicit Transform(const Matrix& m);  // computes the inverse; a singular m has a zero inverse

    static Transform translate(const Vec3& d);
    static Transform scale(const Vec3& s);
    // Rotation by angle_degrees about axis (right-handed, as Mitsuba's `rotate`).
    static Transform rotate(const Vec3& axis, float angle_degrees);
    // Camera-to-world for a camera at `origin` looking at `target` (Mitsuba's `lookat`:
    // +z forward, +y up, +x = cross(up, forward), i.e. to the left in the image).
    static Transform look_at(const Vec3& origin, const Vec3& target, const Vec3& up);

    // this * other: `other` is applied first.
    Transform operator*(const Transform& other) const;
    Transform inverse() const;
    bool is_singular() const { return singular_; }

    Vec3 apply_point(const Vec3& p) const;
    Vec3 apply_vector(const Vec3& v) const;
    // Normals transform with the inverse transpose; the result is not normalised.
    Vec3 apply_normal(const Vec3& n) const;

    const Matrix& matrix() const { return m_; }
    // Determinant of the upper 3x3 part: negative when the transform mirrors (handedness).
    double determinant3x3() const;

  private:
    Transform(const Matrix& m, const Matrix& inv, bool singular)
        : m_(m), inv_(inv), singular_(singular) {}
    Matrix m_;
    Matrix inv_;
    bool singular_ = false;
};

}  // namespace render
