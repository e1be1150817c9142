#pragma once

// Our Ray as Embree's single-ray structures. Scene::intersect/occluded and the bare-Embree
// benchmark loops (bench/ray_queries.cpp) set rays up through these, so they compare like with
// like.

#include <embree3/rtcore.h>

#include <cmath>
#include <cstddef>
#include <cstring>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "core/base/scene_limits.h"
#include "core/math/ray.h"

namespace render {

// Whether Embree may be handed `ray`: a finite origin and direction within kMaxSceneCoordinate
// per axis and t bounds that are not NaN. Embree asserts on other rays (its RayK::valid(), up
// to 1.8e18), which aborts the process; the loaders refuse the transforms that could carry a
// valid ray beyond that inside an instance (ray_transform_problem in
// core/base/ray_transform_check.h), so a ray that passes here stays valid in every instance's
// space (docs/guide/reliability.md, "Resource limits"). NaN fails every comparison. The ray's
// eight floats are compared as two SIMD vectors and the comparison's sign bits read at once
// (movmskps), no branch per float (docs/results/performance-notes.md, "The ray guard at
// Embree's door"); without SSE2, the same comparisons one by one.
inline bool embree_accepts(const Ray& ray) {
    static_assert(sizeof(Ray) == 8 * sizeof(float) && offsetof(Ray, direction) == 12 &&
                  offsetof(Ray, t_min) == 24 && offsetof(Ray, t_max) == 28);
    float v[8];
    std::memcpy(v, &ray, sizeof v);
    constexpr float o = kMaxSceneCoordinate, inf = INFINITY;
#if defined(__SSE2__)
    const __m128 sign = _mm_set1_ps(-0.0f);
    const __m128 first = _mm_andnot_ps(sign, _mm_loadu_ps(v));       // |origin|, |direction.x|
    const __m128 second = _mm_andnot_ps(sign, _mm_loadu_ps(v + 4));  // |direction.yz|, |t|
    const __m128 within = _mm_and_ps(_mm_cmple_ps(first, _mm_set1_ps(o)),
                                     _mm_cmple_ps(second, _mm_setr_ps(o, o, inf, inf)));
    return _mm_movemask_ps(within) == 0xf;
#else
    constexpr float limit[8] = {o, o, o, o, o, o, inf, inf};
    int within = 0;
    for (int i = 0; i < 8; ++i) within += std::abs(v[i]) <= limit[i];
    return within == 8;
#endif
}

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
