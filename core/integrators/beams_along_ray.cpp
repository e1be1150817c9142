#include "core/integrators/beams_along_ray.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "core/scene/embree_ray.h"

namespace render {

bool closest_approach(const Ray& ray, const BeamLine& beam, BeamApproach& out) {
    const Vec3 n = cross(ray.direction, beam.direction);
    const float sin2 = length_squared(n);
    if (!(sin2 >= 1e-5f)) return false;
    // The lines o_r + t_r d_r and o_b + t_b d_b: the offset between them along n is the
    // distance; the parameters solve the 2 x 2 system of the perpendicular conditions.
    const Vec3 w = ray.origin - beam.origin;
    const float b = dot(ray.direction, beam.direction);
    const float d = dot(ray.direction, w), e = dot(beam.direction, w);
    out.t_ray = (b * e - d) / sin2;
    out.t_beam = (e - b * d) / sin2;
    out.sin_theta = std::sqrt(sin2);
    out.distance = std::abs(dot(w, n)) / out.sin_theta;
    return true;
}

namespace {

// What the intersection callback sees of a query (Embree passes the context through).
struct QueryContext {
    RTCIntersectContext context;  // first: Embree's callbacks receive a pointer to it
    const std::vector<BeamLine>* beams;
    float radius;
    BeamsAlongRay::VisitFunction visit;
    void* user;
};

// Single rays only (rtcIntersect1). The ray is never shortened, so every capsule box the
// segment touches is visited, each beam at most once per query.
void capsule_intersect(const RTCIntersectFunctionNArguments* args) {
    if (!args->valid[0]) return;
    const auto* q = reinterpret_cast<const QueryContext*>(args->context);
    const RTCRay& r = reinterpret_cast<const RTCRayHit*>(args->rayhit)->ray;
    const BeamLine& beam = (*q->beams)[args->primID];
    const Ray ray(Vec3(r.org_x, r.org_y, r.org_z), Vec3(r.dir_x, r.dir_y, r.dir_z));
    BeamApproach a;
    if (!closest_approach(ray, beam, a)) return;
    if (!(a.t_ray >= r.tnear && a.t_ray <= r.tfar)) return;
    if (!(a.t_beam >= 0 && a.t_beam <= beam.length)) return;
    if (!(a.distance <= q->radius)) return;
    q->visit(q->user, args->primID, a);
}

}  // namespace

void BeamsAlongRay::capsule_bounds(const RTCBoundsFunctionArguments* args) {
    const auto* self = static_cast<const BeamsAlongRay*>(args->geometryUserPtr);
    const BeamLine& b = (*self->beams_)[args->primID];
    const Vec3 end = b.origin + b.direction * b.length;
    const float r = self->radius_;
    *args->bounds_o = RTCBounds{std::min(b.origin.x, end.x) - r, std::min(b.origin.y, end.y) - r,
                                std::min(b.origin.z, end.z) - r, 0.0f,
                                std::max(b.origin.x, end.x) + r, std::max(b.origin.y, end.y) + r,
                                std::max(b.origin.z, end.z) + r, 0.0f};
}

BeamsAlongRay::BeamsAlongRay() {
    device_ = rtcNewDevice(nullptr);
    if (!device_) throw std::runtime_error("cannot create an Embree device for photon beams");
}

BeamsAlongRay::~BeamsAlongRay() {
    if (scene_) rtcReleaseScene(scene_);
    if (device_) rtcReleaseDevice(device_);
}

void BeamsAlongRay::build(const std::vector<BeamLine>& beams, float radius) {
    beams_ = &beams;
    radius_ = radius;
    bounds_ = Aabb{};
    for (const BeamLine& b : beams) {
        bounds_.expand(b.origin);
        bounds_.expand(b.origin + b.direction * b.length);
    }
    if (!bounds_.empty()) bounds_ = {bounds_.lo - Vec3(radius), bounds_.hi + Vec3(radius)};
    if (scene_) rtcReleaseScene(scene_);
    scene_ = rtcNewScene(device_);
    rtcSetSceneBuildQuality(scene_, RTC_BUILD_QUALITY_LOW);
    if (!beams.empty()) {
        RTCGeometry geometry = rtcNewGeometry(device_, RTC_GEOMETRY_TYPE_USER);
        rtcSetGeometryUserPrimitiveCount(geometry, unsigned(beams.size()));
        rtcSetGeometryUserData(geometry, this);
        rtcSetGeometryBoundsFunction(geometry, capsule_bounds, nullptr);
        rtcSetGeometryIntersectFunction(geometry, capsule_intersect);
        rtcCommitGeometry(geometry);
        rtcAttachGeometry(scene_, geometry);
        rtcReleaseGeometry(geometry);
    }
    rtcCommitScene(scene_);
}

void BeamsAlongRay::query(const Ray& ray, VisitFunction visit, void* user) const {
    // A ray Embree would not accept finds nothing (it was a miss in the scene already).
    if (!scene_ || !beams_ || beams_->empty() || !embree_accepts(ray)) return;
    QueryContext q;
    rtcInitIntersectContext(&q.context);
    q.beams = beams_;
    q.radius = radius_;
    q.visit = visit;
    q.user = user;
    RTCRayHit rh = to_rtc_ray_hit(ray);
    rtcIntersect1(scene_, &q.context, &rh);
}

}  // namespace render
