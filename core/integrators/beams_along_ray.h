#pragma once

// Which photon beams pass within a radius r of a ray segment: the lookup of upbp's photon-beam
// estimate (B-B1D), where every camera segment in a medium gathers the beams around it. Each
// beam is a line segment; its capsule of radius r is bounded by a box in an Embree BVH of user
// geometry whose intersection callback computes the closest approach of the two lines, records
// each beam within r and never reports a hit, so the traversal visits all of them (as
// PointsAlongRay does for photon points). Built once per iteration, then read-only and shared
// by all threads; the Embree device lives as long as the object.

#include <embree3/rtcore.h>

#include <cstdint>
#include <type_traits>
#include <vector>

#include "core/base/shape.h"
#include "core/math/ray.h"
#include "core/math/vec.h"

namespace render {

// A beam as the lookup sees it: origin, unit direction, length (finite, >= 0).
struct BeamLine {
    Vec3 origin;
    Vec3 direction;
    float length = 0;
};

// The closest approach of a ray (unit direction) and a beam: parameters along each, the
// distance between the lines there and sin of the angle between them.
struct BeamApproach {
    float t_ray = 0, t_beam = 0;
    float distance = 0;
    float sin_theta = 0;
};

// The closest approach of the two lines; empty when they are parallel to within
// sin^2(theta) < 1e-5 (SmallUPBP's test, VcmMis::beams_parallel).
bool closest_approach(const Ray& ray, const BeamLine& beam, BeamApproach& out);

class BeamsAlongRay {
  public:
    BeamsAlongRay();
    ~BeamsAlongRay();
    BeamsAlongRay(const BeamsAlongRay&) = delete;
    BeamsAlongRay& operator=(const BeamsAlongRay&) = delete;

    // Indexes `beams` (kept by reference: it must outlive the queries) as capsules of `radius`.
    void build(const std::vector<BeamLine>& beams, float radius);

    // Calls visit(i, approach) for every beam i whose closest approach to the ray's line is at
    // t_ray in [ray.t_min, ray.t_max], at t_beam in [0, length] and within the radius, the
    // lines not parallel. ray.direction must be unit length. The order is unspecified.
    template <typename Visit>
    void for_each_near(const Ray& ray, Visit&& visit) const {
        query(
            ray,
            [](void* user, uint32_t i, const BeamApproach& a) {
                (*static_cast<std::remove_reference_t<Visit>*>(user))(i, a);
            },
            &visit);
    }

    using VisitFunction = void (*)(void* user, uint32_t index, const BeamApproach& approach);
    void query(const Ray& ray, VisitFunction visit, void* user) const;

    float radius() const { return radius_; }
    // The box of the indexed capsules (empty when none): no query outside it finds a beam.
    const Aabb& bounds() const { return bounds_; }

  private:
    static void capsule_bounds(const RTCBoundsFunctionArguments* args);

    RTCDevice device_ = nullptr;
    RTCScene scene_ = nullptr;
    const std::vector<BeamLine>* beams_ = nullptr;
    float radius_ = 0;
    Aabb bounds_;
};

}  // namespace render
