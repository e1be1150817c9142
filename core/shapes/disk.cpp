#include "core/shapes/disk.h"

#include <cmath>
#include <sstream>

#include "core/base/error.h"
#include "core/math/constants.h"
#include "core/sampling/warp.h"
#include "core/shapes/user_geometry.h"
#include "core/shapes/uv_wanted.h"

namespace render {
namespace {

// Ray parameter of the hit with the object-space unit disk, or a negative value. The affine map
// keeps the ray parameter, so t is also the world-space distance parameter.
double intersect_disk(const Transform& to_object, const float org[3], const float dir[3]) {
    const auto& m = to_object.matrix();
    double o[3], d[3];
    for (int i = 0; i < 3; ++i) {
        o[i] = m[i][0] * org[0] + m[i][1] * org[1] + m[i][2] * org[2] + m[i][3];
        d[i] = m[i][0] * dir[0] + m[i][1] * dir[1] + m[i][2] * dir[2];
    }
    if (d[2] == 0) return -1.0;
    double t = -o[2] / d[2];
    double x = o[0] + t * d[0], y = o[1] + t * d[1];
    return x * x + y * y <= 1.0 ? t : -1.0;
}

}  // namespace

Disk::Disk(const Transform& to_world, bool flip_normals, std::string name)
    : to_world_(to_world),
      to_object_(to_world.inverse()),
      flip_normals_(flip_normals),
      name_(std::move(name)) {
    if (to_world.is_singular()) throw SceneError(name_ + ": to_world transform is singular");
    center_ = to_world.apply_point(Vec3(0, 0, 0));
    Vec3 n = normalize(to_world.apply_normal(Vec3(0, 0, 1)));
    normal_ = flip_normals ? -n : n;
    // An affine image of the unit disk is an ellipse with area pi |a x b|.
    area_ = kPi * length(cross(to_world.apply_vector(Vec3(1, 0, 0)),
                               to_world.apply_vector(Vec3(0, 1, 0))));
}

std::optional<double> Disk::nearest_hit(const float org[3], const float dir[3], float t_min,
                                        float t_max) const {
    double t = intersect_disk(to_object_, org, dir);
    if (!(t > t_min && t < t_max)) return std::nullopt;
    return t;
}

void Disk::fill_interaction(const Ray& ray, float t, unsigned prim_id, float u, float v,
                            HitDetail detail, SurfaceInteraction& si) const {
    Vec3 local = to_object_.apply_point(ray.at(t));
    local.z = 0;  // project onto the disk plane
    si.p = to_world_.apply_point(local);
    si.t = t;
    si.geometric_normal = normal_;
    si.shading = Frame::from_normal(normal_);
    const bool with_uv = uv_wanted(*this, detail);
    if (with_uv) {
        si.uv = uv_of_local(local.x, local.y);
        // u = r: dp/du is the radial direction (zero at the centre).
        const float r = std::sqrt(local.x * local.x + local.y * local.y);
        si.dpdu = r > 0 ? to_world_.apply_vector(Vec3(local.x / r, local.y / r, 0)) : Vec3(0.0f);
        // v = phi / 2 pi: dp/dv = 2 pi (-y, x, 0), zero at the centre.
        si.dpdv = to_world_.apply_vector(Vec3(-local.y, local.x, 0) * (2 * kPi));
    }
    finish_interaction(prim_id, u, v, with_uv, si);
}

Vec2 Disk::uv_of_local(float x, float y) {
    const float r = std::sqrt(x * x + y * y);
    const float phi = std::atan2(y, x);
    return Vec2(r, (phi < 0 ? phi + 2 * kPi : phi) * kInv2Pi);
}

Vec2 Disk::uv_at(const Vec3& p) const {
    const Vec3 local = to_object_.apply_point(p);
    return uv_of_local(local.x, local.y);
}

Aabb Disk::bounds() const {
    Aabb b;
    // The ellipse lies inside the image of the square [-1,1]^2.
    for (float x : {-1.0f, 1.0f})
        for (float y : {-1.0f, 1.0f}) b.expand(to_world_.apply_point(Vec3(x, y, 0)));
    return b;
}

ShapeSample Disk::sample_area(Vec2 u) const {
    Vec2 d = warp::square_to_uniform_disk_concentric(u);
    ShapeSample s;
    s.p = to_world_.apply_point(Vec3(d.x, d.y, 0));
    s.n = normal_;
    s.uv = uv_of_local(d.x, d.y);
    s.pdf_area = area_ > 0 ? 1.0f / area_ : 0.0f;
    return s;
}

std::string Disk::to_string() const {
    std::ostringstream out;
    out << "Disk[" << name_ << ", center " << center_ << ", area " << area_ << "]";
    return out.str();
}

}  // namespace render
