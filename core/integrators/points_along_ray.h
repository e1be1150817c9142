#pragma once

// Which of a set of points lie within a radius r of a ray segment: the lookup of the beam
// radiance estimate (P-B2D), where every camera segment in a medium gathers the photon points
// around it. The points are balls of radius r in an Embree BVH of user geometry whose
// intersection callback records each ball the ray passes through and never reports a hit, so
// the traversal visits all of them. Built once per iteration, then read-only and shared by all
// threads; the Embree device lives as long as the object (iterations rebuild only the BVH).

#include <embree3/rtcore.h>

#include <cstdint>
#include <vector>

#include "core/base/shape.h"
#include "core/math/ray.h"
#include "core/math/vec.h"

namespace render {

class PointsAlongRay {
  public:
    PointsAlongRay();
    ~PointsAlongRay();
    PointsAlongRay(const PointsAlongRay&) = delete;
    PointsAlongRay& operator=(const PointsAlongRay&) = delete;

    // Indexes the first `count` of `positions` (all when count exceeds the size; kept by
    // reference: it must outlive the queries) as balls of `radius`.
    void build(const std::vector<Vec3>& positions, float radius, size_t count = SIZE_MAX);

    // Calls visit(i, t, distance2) for every point i whose closest approach to the ray's line
    // is at parameter t in [ray.t_min, ray.t_max] and at squared distance distance2 <= r^2.
    // ray.direction must be unit length. The order of the visits is unspecified.
    template <typename Visit>
    void for_each_near(const Ray& ray, Visit&& visit) const {
        query(
            ray,
            [](void* user, uint32_t i, float t, float distance2) {
                (*static_cast<Visit*>(user))(i, t, distance2);
            },
            &visit);
    }

    using VisitFunction = void (*)(void* user, uint32_t index, float t, float distance2);
    void query(const Ray& ray, VisitFunction visit, void* user) const;

    float radius() const { return radius_; }
    // The box of the indexed balls (empty when none): no query outside it finds a point.
    const Aabb& bounds() const { return bounds_; }

  private:
    static void ball_bounds(const RTCBoundsFunctionArguments* args);

    RTCDevice device_ = nullptr;
    RTCScene scene_ = nullptr;
    const std::vector<Vec3>* positions_ = nullptr;
    size_t count_ = 0;  // the indexed prefix of *positions_
    float radius_ = 0;
    Aabb bounds_;
};

}  // namespace render
