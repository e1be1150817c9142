#include "core/scene/shapes/disk.h"

#include <cmath>
#include <limits>
#include <sstream>

#include "core/math/constants.h"
#include "core/sampling/warp.h"
#include "core/scene/error.h"

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

void disk_bounds(const RTCBoundsFunctionArguments* args) {
    Aabb b = static_cast<const Disk*>(args->geometryUserPtr)->bounds();
    args->bounds_o->lower_x = b.lo.x;
    args->bounds_o->lower_y = b.lo.y;
    args->bounds_o->lower_z = b.lo.z;
    args->bounds_o->upper_x = b.hi.x;
    args->bounds_o->upper_y = b.hi.y;
    args->bounds_o->upper_z = b.hi.z;
}

}  // namespace

// Embree callbacks need the object transform; friend-free access through a small struct.
struct DiskCallbacks {
    static void intersect(const RTCIntersectFunctionNArguments* args) {
        if (!args->valid[0]) return;
        const auto* disk = static_cast<const Disk*>(args->geometryUserPtr);
        auto* rayhit = reinterpret_cast<RTCRayHit*>(args->rayhit);
        RTCRay& ray = rayhit->ray;
        const float org[3] = {ray.org_x, ray.org_y, ray.org_z};
        const float dir[3] = {ray.dir_x, ray.dir_y, ray.dir_z};
        double t = intersect_disk(disk->to_object_, org, dir);
        if (!(t > ray.tnear && t < ray.tfar)) return;
        ray.tfar = float(t);
        RTCHit& hit = rayhit->hit;
        hit.Ng_x = disk->normal_.x;
        hit.Ng_y = disk->normal_.y;
        hit.Ng_z = disk->normal_.z;
        hit.u = hit.v = 0;
        hit.primID = args->primID;
        hit.geomID = args->geomID;
        hit.instID[0] = args->context->instID[0];
    }
    static void occluded(const RTCOccludedFunctionNArguments* args) {
        if (!args->valid[0]) return;
        const auto* disk = static_cast<const Disk*>(args->geometryUserPtr);
        auto* ray = reinterpret_cast<RTCRay*>(args->ray);
        const float org[3] = {ray->org_x, ray->org_y, ray->org_z};
        const float dir[3] = {ray->dir_x, ray->dir_y, ray->dir_z};
        double t = intersect_disk(disk->to_object_, org, dir);
        if (t > ray->tnear && t < ray->tfar) ray->tfar = -std::numeric_limits<float>::infinity();
    }
};

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

unsigned Disk::attach(RTCDevice device, RTCScene scene) const {
    RTCGeometry geometry = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_USER);
    rtcSetGeometryUserPrimitiveCount(geometry, 1);
    rtcSetGeometryUserData(geometry, const_cast<Disk*>(this));
    rtcSetGeometryBoundsFunction(geometry, disk_bounds, nullptr);
    rtcSetGeometryIntersectFunction(geometry, DiskCallbacks::intersect);
    rtcSetGeometryOccludedFunction(geometry, DiskCallbacks::occluded);
    rtcCommitGeometry(geometry);
    unsigned id = rtcAttachGeometry(scene, geometry);
    rtcReleaseGeometry(geometry);
    return id;
}

void Disk::fill_interaction(const Ray& ray, float t, unsigned, float, float,
                            SurfaceInteraction& si) const {
    Vec3 local = to_object_.apply_point(ray.at(t));
    local.z = 0;  // project onto the disk plane
    si.p = to_world_.apply_point(local);
    si.t = t;
    si.geometric_normal = normal_;
    si.shading = Frame::from_normal(normal_);
    float r = std::sqrt(local.x * local.x + local.y * local.y);
    float phi = std::atan2(local.y, local.x);
    si.uv = Vec2(r, (phi < 0 ? phi + 2 * kPi : phi) * kInv2Pi);
    si.shape = this;
    si.bsdf = bsdf;
    si.emitter = emitter;
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
    s.pdf_area = area_ > 0 ? 1.0f / area_ : 0.0f;
    return s;
}

std::string Disk::to_string() const {
    std::ostringstream out;
    out << "Disk[" << name_ << ", center " << center_ << ", area " << area_ << "]";
    return out.str();
}

}  // namespace render
