#include "core/integrators/points_along_ray.h"

#include <algorithm>
#include <stdexcept>

#include "core/scene/embree_ray.h"

namespace render {
namespace {

// What the intersection callback sees of a query: Embree passes the context through, so the
// query's state rides behind it.
struct QueryContext {
    RTCIntersectContext context;  // first: Embree's callbacks receive a pointer to it
    const std::vector<Vec3>* positions;
    float radius2;
    PointsAlongRay::VisitFunction visit;
    void* user;
};

}  // namespace

void PointsAlongRay::ball_bounds(const RTCBoundsFunctionArguments* args) {
    const auto* self = static_cast<const PointsAlongRay*>(args->geometryUserPtr);
    const Vec3& p = (*self->positions_)[args->primID];
    const float r = self->radius_;
    *args->bounds_o = RTCBounds{p.x - r, p.y - r, p.z - r, 0.0f, p.x + r, p.y + r, p.z + r, 0.0f};
}

namespace {

// Single rays only (rtcIntersect1): N is 1. The ray is never shortened, so every ball the
// segment touches is visited; each ball is one primitive, visited at most once per query.
void ball_intersect(const RTCIntersectFunctionNArguments* args) {
    if (!args->valid[0]) return;
    const auto* q = reinterpret_cast<const QueryContext*>(args->context);
    const RTCRay& ray = reinterpret_cast<const RTCRayHit*>(args->rayhit)->ray;
    const Vec3& p = (*q->positions)[args->primID];
    const Vec3 o(ray.org_x, ray.org_y, ray.org_z), d(ray.dir_x, ray.dir_y, ray.dir_z);
    const Vec3 op = p - o;
    const float t = dot(op, d);
    if (!(t >= ray.tnear && t <= ray.tfar)) return;
    const float distance2 = length_squared(op - d * t);
    if (!(distance2 <= q->radius2)) return;
    q->visit(q->user, args->primID, t, distance2);
}

}  // namespace

PointsAlongRay::PointsAlongRay() {
    device_ = rtcNewDevice(nullptr);
    if (!device_) throw std::runtime_error("cannot create an Embree device for photon lookups");
}

PointsAlongRay::~PointsAlongRay() {
    if (scene_) rtcReleaseScene(scene_);
    if (device_) rtcReleaseDevice(device_);
}

void PointsAlongRay::build(const std::vector<Vec3>& positions, float radius, size_t count) {
    positions_ = &positions;
    count_ = std::min(count, positions.size());
    radius_ = radius;
    bounds_ = Aabb{};
    for (size_t i = 0; i < count_; ++i) bounds_.expand(positions[i]);
    if (!bounds_.empty()) bounds_ = {bounds_.lo - Vec3(radius), bounds_.hi + Vec3(radius)};
    if (scene_) rtcReleaseScene(scene_);
    scene_ = rtcNewScene(device_);
    rtcSetSceneBuildQuality(scene_, RTC_BUILD_QUALITY_LOW);
    if (count_ > 0) {
        RTCGeometry geometry = rtcNewGeometry(device_, RTC_GEOMETRY_TYPE_USER);
        rtcSetGeometryUserPrimitiveCount(geometry, unsigned(count_));
        rtcSetGeometryUserData(geometry, this);
        rtcSetGeometryBoundsFunction(geometry, ball_bounds, nullptr);
        rtcSetGeometryIntersectFunction(geometry, ball_intersect);
        rtcCommitGeometry(geometry);
        rtcAttachGeometry(scene_, geometry);
        rtcReleaseGeometry(geometry);
    }
    rtcCommitScene(scene_);
}

void PointsAlongRay::query(const Ray& ray, VisitFunction visit, void* user) const {
    // A ray Embree would not accept finds nothing (it was a miss in the scene already).
    if (!scene_ || !positions_ || count_ == 0 || !embree_accepts(ray)) return;
    QueryContext q;
    rtcInitIntersectContext(&q.context);
    q.positions = positions_;
    q.radius2 = radius_ * radius_;
    q.visit = visit;
    q.user = user;
    RTCRayHit rh = to_rtc_ray_hit(ray);
    rtcIntersect1(scene_, &q.context, &rh);
}

}  // namespace render
