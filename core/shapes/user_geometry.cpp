#include "core/shapes/user_geometry.h"

#include <cmath>
#include <limits>

#include "core/shapes/alpha_cutout.h"

namespace render {
namespace {

void analytic_bounds(const RTCBoundsFunctionArguments* args) {
    Aabb b = static_cast<const AnalyticShape*>(args->geometryUserPtr)->bounds();
    *args->bounds_o = RTCBounds{b.lo.x, b.lo.y, b.lo.z, 0.0f, b.hi.x, b.hi.y, b.hi.z, 0.0f};
}

// The nearest hit that the shape's cut-out keeps (the nearest hit without one). A cut-out
// hit lets the ray go on to the surface's next hit: an analytic shape has at most two.
std::optional<double> nearest_kept_hit(const AnalyticShape& shape, const float org[3],
                                       const float dir[3], float t_min, float t_max) {
    std::optional<double> t = shape.nearest_hit(org, dir, t_min, t_max);
    if (!shape.alpha) return t;
    for (int hit = 0; hit < 4 && t; ++hit) {
        const Vec3 p(float(org[0] + *t * dir[0]), float(org[1] + *t * dir[1]),
                     float(org[2] + *t * dir[2]));
        if (shape.alpha->keeps_hit(shape.uv_at(p), org, dir, float(*t))) return t;
        t = shape.nearest_hit(org, dir, std::nextafter(float(*t), t_max), t_max);
    }
    return std::nullopt;
}

// Closest hits are single rays (rtcIntersect1), so N is always 1 here.
void analytic_intersect(const RTCIntersectFunctionNArguments* args) {
    if (!args->valid[0]) return;
    const auto* shape = static_cast<const AnalyticShape*>(args->geometryUserPtr);
    auto* rayhit = reinterpret_cast<RTCRayHit*>(args->rayhit);
    RTCRay& ray = rayhit->ray;
    const float org[3] = {ray.org_x, ray.org_y, ray.org_z};
    const float dir[3] = {ray.dir_x, ray.dir_y, ray.dir_z};
    std::optional<double> t = nearest_kept_hit(*shape, org, dir, ray.tnear, ray.tfar);
    if (!t) return;
    ray.tfar = float(*t);
    RTCHit& hit = rayhit->hit;
    hit.Ng_x = hit.Ng_y = hit.Ng_z = 0;  // computed by fill_interaction()
    hit.u = hit.v = 0;
    hit.primID = args->primID;
    hit.geomID = args->geomID;
    hit.instID[0] = args->context->instID[0];
}

// Shadow rays come one at a time (rtcOccluded1, N = 1) or in packets of N from the stream
// query of Scene's batched occluded(): lane by lane.
void analytic_occluded(const RTCOccludedFunctionNArguments* args) {
    const auto* shape = static_cast<const AnalyticShape*>(args->geometryUserPtr);
    RTCRayN* ray = args->ray;
    const unsigned n = args->N;
    for (unsigned i = 0; i < n; ++i) {
        if (!args->valid[i]) continue;
        const float org[3] = {RTCRayN_org_x(ray, n, i), RTCRayN_org_y(ray, n, i),
                              RTCRayN_org_z(ray, n, i)};
        const float dir[3] = {RTCRayN_dir_x(ray, n, i), RTCRayN_dir_y(ray, n, i),
                              RTCRayN_dir_z(ray, n, i)};
        if (nearest_kept_hit(*shape, org, dir, RTCRayN_tnear(ray, n, i), RTCRayN_tfar(ray, n, i)))
            RTCRayN_tfar(ray, n, i) = -std::numeric_limits<float>::infinity();
    }
}

}  // namespace

unsigned AnalyticShape::attach(RTCDevice device, RTCScene scene) const {
    RTCGeometry geometry = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_USER);
    rtcSetGeometryUserPrimitiveCount(geometry, 1);
    // Embree's API takes a non-const pointer; the callbacks only read the shape.
    rtcSetGeometryUserData(geometry, const_cast<AnalyticShape*>(this));
    rtcSetGeometryBoundsFunction(geometry, analytic_bounds, nullptr);
    rtcSetGeometryIntersectFunction(geometry, analytic_intersect);
    rtcSetGeometryOccludedFunction(geometry, analytic_occluded);
    rtcCommitGeometry(geometry);
    unsigned id = rtcAttachGeometry(scene, geometry);
    rtcReleaseGeometry(geometry);
    return id;
}

}  // namespace render
