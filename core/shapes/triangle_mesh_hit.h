#pragma once

// TriangleMesh::fill_hit, inline so that Scene::intersect fills a mesh hit without a virtual
// call and a call frame (docs/results/performance-notes.md, "Closest hits through
// Scene::intersect").

#include <cstddef>
#include <cstring>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "core/shapes/triangle_mesh.h"
#include "core/shapes/uv_wanted.h"

namespace render {

inline void TriangleMesh::fill_hit(const Ray& ray, float t, unsigned prim_id, float u, float v,
                                   HitDetail detail, SurfaceInteraction& si) const {
    if (!frames_per_triangle_) [[unlikely]] {
        // Interpolated vertex normals, or degenerate triangles: out of line, so that the
        // common case keeps its values in registers.
        fill_hit_interpolated(ray, t, prim_id, u, v, si);
    } else {
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
        _mm_storeu_ps(reinterpret_cast<float*>(reinterpret_cast<char*>(&si) +
                                               offsetof(SurfaceInteraction, p)),
                      p);
#else
        si.p = Vec3(r.p[0][0], r.p[0][1], r.p[0][2]) * b0 +
               Vec3(r.p[1][0], r.p[1][1], r.p[1][2]) * u +
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
    const bool with_uv = uv_wanted(*this, detail);
    if (with_uv) [[unlikely]]
        fill_uv(prim_id, u, v, si);
    finish_interaction(prim_id, u, v, with_uv, si);
}

}  // namespace render
