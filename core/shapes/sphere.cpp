#include "core/shapes/sphere.h"

#include <cmath>
#include <sstream>

#include "core/math/constants.h"
#include "core/sampling/warp.h"
#include "core/shapes/user_geometry.h"
#include "core/shapes/uv_wanted.h"

namespace render {
namespace {

// Roots of |o + t d - c|^2 = r^2 in double precision, using the numerically stable form of
// the quadratic (no cancellation between b and the discriminant).
bool intersect_sphere(const Vec3& center, double radius, const float org[3], const float dir[3],
                      double& t0, double& t1) {
    double ox = double(org[0]) - center.x, oy = double(org[1]) - center.y,
           oz = double(org[2]) - center.z;
    double dx = dir[0], dy = dir[1], dz = dir[2];
    double a = dx * dx + dy * dy + dz * dz;
    double b = 2.0 * (ox * dx + oy * dy + oz * dz);
    double c = ox * ox + oy * oy + oz * oz - radius * radius;
    double disc = b * b - 4.0 * a * c;
    if (disc < 0 || a == 0) return false;
    double q = -0.5 * (b + std::copysign(std::sqrt(disc), b));
    t0 = q / a;
    t1 = q != 0 ? c / q : t0;
    if (t0 > t1) std::swap(t0, t1);
    return true;
}

}  // namespace

Sphere::Sphere(const Vec3& center, float radius, bool flip_normals, std::string name,
               const Frame& axes)
    : center_(center),
      radius_(radius),
      flip_normals_(flip_normals),
      name_(std::move(name)),
      axes_(axes) {}

std::optional<double> Sphere::nearest_hit(const float org[3], const float dir[3], float t_min,
                                          float t_max) const {
    double t0, t1;
    if (!intersect_sphere(center_, radius_, org, dir, t0, t1)) return std::nullopt;
    double t = t0 > t_min ? t0 : t1;  // from inside, the far root
    if (!(t > t_min && t < t_max)) return std::nullopt;
    return t;
}

void Sphere::fill_interaction(const Ray& ray, float t, unsigned prim_id, float u, float v,
                              HitDetail detail, SurfaceInteraction& si) const {
    Vec3 p = ray.at(t);
    Vec3 n = p - center_;
    float len = length(n);
    n = len > 0 ? n / len : Vec3(0, 0, 1);
    // Re-project onto the surface: removes the error of origin + t * direction.
    si.p = center_ + n * radius_;
    si.t = t;
    const bool with_uv = uv_wanted(*this, detail);
    if (with_uv) {
        si.uv = uv_of_direction(n);
        // u = phi / 2pi turns about the object's z axis (the other way in a mirrored frame):
        // dp/du = 2 pi z x (p - c); zero at the poles.
        const float handedness = dot(cross(axes_.s, axes_.t), axes_.n) < 0 ? -1.0f : 1.0f;
        si.dpdu = cross(axes_.n, n * radius_) * (2 * kPi * handedness);
        // v = theta / pi from the object's +z: dp/dv = pi r (cos(theta) n - z) / sin(theta)
        // (unit dp/dtheta times pi r); zero at the poles.
        const float cos_theta = dot(n, axes_.n);
        const float sin_theta = std::sqrt(std::max(0.0f, 1 - cos_theta * cos_theta));
        si.dpdv =
            sin_theta > 0 ? (n * cos_theta - axes_.n) * (kPi * radius_ / sin_theta) : Vec3(0.0f);
    }
    if (flip_normals_) n = -n;
    si.geometric_normal = n;
    si.shading = Frame::from_normal(n);
    finish_interaction(prim_id, u, v, with_uv, si);
}

Vec2 Sphere::uv_of_direction(const Vec3& d) const {
    // From the outward direction in object space, whichever way the normal faces.
    const Vec3 local = axes_.to_local(d);
    const float theta = std::acos(std::clamp(local.z, -1.0f, 1.0f));
    const float phi = std::atan2(local.y, local.x);
    return Vec2((phi < 0 ? phi + 2 * kPi : phi) * kInv2Pi, theta * kInvPi);
}

Vec2 Sphere::uv_at(const Vec3& p) const {
    const Vec3 d = p - center_;
    const float len = length(d);
    return uv_of_direction(len > 0 ? d / len : Vec3(0, 0, 1));
}

Aabb Sphere::bounds() const {
    Aabb b;
    b.expand(center_ - Vec3(radius_));
    b.expand(center_ + Vec3(radius_));
    return b;
}

float Sphere::surface_area() const {
    return 4.0f * kPi * radius_ * radius_;
}

ShapeSample Sphere::sample_area(Vec2 u) const {
    Vec3 d = warp::square_to_uniform_sphere(u);
    ShapeSample s;
    s.p = center_ + d * radius_;
    s.n = flip_normals_ ? -d : d;
    s.uv = uv_of_direction(d);
    s.pdf_area = 1.0f / surface_area();
    return s;
}

std::string Sphere::to_string() const {
    std::ostringstream out;
    out << "Sphere[" << name_ << ", center " << center_ << ", radius " << radius_ << "]";
    return out.str();
}

}  // namespace render
