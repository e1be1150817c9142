#include "core/scene/shapes/sphere.h"

#include <cmath>
#include <limits>
#include <sstream>

#include "core/math/constants.h"
#include "core/sampling/warp.h"

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

void sphere_bounds(const RTCBoundsFunctionArguments* args) {
    const auto* sphere = static_cast<const Sphere*>(args->geometryUserPtr);
    Aabb b = sphere->bounds();
    args->bounds_o->lower_x = b.lo.x;
    args->bounds_o->lower_y = b.lo.y;
    args->bounds_o->lower_z = b.lo.z;
    args->bounds_o->upper_x = b.hi.x;
    args->bounds_o->upper_y = b.hi.y;
    args->bounds_o->upper_z = b.hi.z;
}

// The scene only issues single rays (rtcIntersect1/rtcOccluded1), so N is always 1.
void sphere_intersect(const RTCIntersectFunctionNArguments* args) {
    if (!args->valid[0]) return;
    const auto* sphere = static_cast<const Sphere*>(args->geometryUserPtr);
    auto* rayhit = reinterpret_cast<RTCRayHit*>(args->rayhit);
    RTCRay& ray = rayhit->ray;
    const float org[3] = {ray.org_x, ray.org_y, ray.org_z};
    const float dir[3] = {ray.dir_x, ray.dir_y, ray.dir_z};
    double t0, t1;
    if (!intersect_sphere(sphere->center(), sphere->radius(), org, dir, t0, t1)) return;
    double t = t0 > ray.tnear ? t0 : t1;
    if (!(t > ray.tnear && t < ray.tfar)) return;
    ray.tfar = float(t);
    RTCHit& hit = rayhit->hit;
    Vec3 p(float(org[0] + t * dir[0]), float(org[1] + t * dir[1]), float(org[2] + t * dir[2]));
    Vec3 n = p - sphere->center();
    hit.Ng_x = n.x;
    hit.Ng_y = n.y;
    hit.Ng_z = n.z;
    hit.u = hit.v = 0;
    hit.primID = args->primID;
    hit.geomID = args->geomID;
    hit.instID[0] = args->context->instID[0];
}

void sphere_occluded(const RTCOccludedFunctionNArguments* args) {
    if (!args->valid[0]) return;
    const auto* sphere = static_cast<const Sphere*>(args->geometryUserPtr);
    auto* ray = reinterpret_cast<RTCRay*>(args->ray);
    const float org[3] = {ray->org_x, ray->org_y, ray->org_z};
    const float dir[3] = {ray->dir_x, ray->dir_y, ray->dir_z};
    double t0, t1;
    if (!intersect_sphere(sphere->center(), sphere->radius(), org, dir, t0, t1)) return;
    if ((t0 > ray->tnear && t0 < ray->tfar) || (t1 > ray->tnear && t1 < ray->tfar))
        ray->tfar = -std::numeric_limits<float>::infinity();
}

}  // namespace

Sphere::Sphere(const Vec3& center, float radius, bool flip_normals, std::string name)
    : center_(center), radius_(radius), flip_normals_(flip_normals), name_(std::move(name)) {}

unsigned Sphere::attach(RTCDevice device, RTCScene scene) const {
    RTCGeometry geometry = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_USER);
    rtcSetGeometryUserPrimitiveCount(geometry, 1);
    rtcSetGeometryUserData(geometry, const_cast<Sphere*>(this));
    rtcSetGeometryBoundsFunction(geometry, sphere_bounds, nullptr);
    rtcSetGeometryIntersectFunction(geometry, sphere_intersect);
    rtcSetGeometryOccludedFunction(geometry, sphere_occluded);
    rtcCommitGeometry(geometry);
    unsigned id = rtcAttachGeometry(scene, geometry);
    rtcReleaseGeometry(geometry);
    return id;
}

void Sphere::fill_interaction(const Ray& ray, float t, unsigned, float, float,
                              SurfaceInteraction& si) const {
    Vec3 p = ray.at(t);
    Vec3 n = p - center_;
    float len = length(n);
    n = len > 0 ? n / len : Vec3(0, 0, 1);
    // Re-project onto the surface: removes the error of origin + t * direction.
    si.p = center_ + n * radius_;
    si.t = t;
    if (flip_normals_) n = -n;
    si.geometric_normal = n;
    si.shading = Frame::from_normal(n);
    float theta = std::acos(std::clamp(n.z, -1.0f, 1.0f));
    float phi = std::atan2(n.y, n.x);
    si.uv = Vec2((phi < 0 ? phi + 2 * kPi : phi) * kInv2Pi, theta * kInvPi);
    si.shape = this;
    si.bsdf = bsdf;
    si.emitter = emitter;
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
    s.pdf_area = 1.0f / surface_area();
    return s;
}

std::string Sphere::to_string() const {
    std::ostringstream out;
    out << "Sphere[" << name_ << ", center " << center_ << ", radius " << radius_ << "]";
    return out.str();
}

}  // namespace render
