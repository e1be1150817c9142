#pragma once

// TriangleMesh::fill_plain_hit, inline so that Scene::intersect fills a mesh hit without a
// virtual call, a call frame or a test (docs/results/performance-notes.md, "Closest hits through
// Scene::intersect").

#include <cstddef>
#include <cstring>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "core/shapes/triangle_mesh.h"

namespace render {

inline void TriangleMesh::fill_from_record(float t, unsigned prim_id, float u, float v,
                                           SurfaceInteraction& si) const {
    const HitRecord& r = hit_records_[prim_id];
    // Interpolating the vertices is more accurate than origin + t * direction far from the
    // ray origin.
    const float b0 = 1.0f - u - v;
#if defined(__SSE2__)
    // Lane by lane the scalar (p0 b0 + p1 u) + p2 v: the same bits. The store writes a
    // fourth float over geometric_normal.x, which the copy below overwrites.
    static_assert(offsetof(SurfaceInteraction, geometric_normal) ==
                  offsetof(SurfaceInteraction, p) + 3 * sizeof(float));
    const __m128 p = _mm_add_ps(_mm_add_ps(_mm_mul_ps(_mm_load_ps(r.p[0]), _mm_set1_ps(b0)),
                                           _mm_mul_ps(_mm_load_ps(r.p[1]), _mm_set1_ps(u))),
                                _mm_mul_ps(_mm_load_ps(r.p[2]), _mm_set1_ps(v)));
    _mm_storeu_ps(
        reinterpret_cast<float*>(reinterpret_cast<char*>(&si) + offsetof(SurfaceInteraction, p)),
        p);
#else
    si.p = Vec3(r.p[0][0], r.p[0][1], r.p[0][2]) * b0 + Vec3(r.p[1][0], r.p[1][1], r.p[1][2]) * u +
           Vec3(r.p[2][0], r.p[2][1], r.p[2][2]) * v;
#endif
    // The normal and the frame follow each other in both structures.
    static_assert(offsetof(SurfaceInteraction, shading) ==
                      offsetof(SurfaceInteraction, geometric_normal) + sizeof(Vec3) &&
                  offsetof(HitRecord, frame) == offsetof(HitRecord, normal) + sizeof(Vec3));
    std::memcpy(reinterpret_cast<char*>(&si) + offsetof(SurfaceInteraction, geometric_normal),
                &r.normal, sizeof(Vec3) + sizeof(Frame));
    si.t = t;
}

inline void TriangleMesh::fill_plain_hit(float t, unsigned prim_id, float u, float v,
                                         SurfaceInteraction& si) const {
    fill_from_record(t, prim_id, u, v, si);
    finish_interaction(prim_id, u, v, false, si);
}

}  // namespace render
