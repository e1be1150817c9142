#pragma once

// Our Ray as Embree's single-ray structures. Scene::intersect/occluded and the bare-Embree
// benchmark loops (bench/ray_queries.cpp) set rays up through these, so they compare like with
// like.

#include <embree3/rtcore.h>

#include "core/math/ray.h"

namespace render {

inline RTCRay to_rtc_ray(const Ray& ray) {
    RTCRay r;
    r.org_x = ray.origin.x;
    r.org_y = ray.origin.y;
    r.org_z = ray.origin.z;
    r.dir_x = ray.direction.x;
    r.dir_y = ray.direction.y;
    r.dir_z = ray.direction.z;
    r.tnear = ray.t_min;
    r.tfar = ray.t_max;
    r.time = 0;
    r.mask = 0xffffffffu;
    r.id = 0;
    r.flags = 0;
    return r;
}

// A ray with no hit yet, for rtcIntersect1.
inline RTCRayHit to_rtc_ray_hit(const Ray& ray) {
    RTCRayHit rh;
    rh.ray = to_rtc_ray(ray);
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    return rh;
}

}  // namespace render
