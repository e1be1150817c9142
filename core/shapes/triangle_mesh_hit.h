#pragma once

// TriangleMesh::fill_hit, inline so that Scene::intersect fills a mesh hit without a virtual
// call and a call frame (docs/results/performance-notes.md, "Closest hits through
// Scene::intersect").

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
        const uint32_t* index = &indices_[3 * size_t(prim_id)];
        const Vec3 &p0 = positions_[index[0]], &p1 = positions_[index[1]],
                   &p2 = positions_[index[2]];
        // Interpolating the vertices is more accurate than origin + t * direction far from the
        // ray origin.
        si.p = p0 * (1.0f - u - v) + p1 * u + p2 * v;
        si.t = t;
        si.geometric_normal = face_normals_[prim_id];
        si.shading = flat_frames_[prim_id];
    }
    const bool with_uv = uv_wanted(*this, detail);
    if (with_uv) [[unlikely]]
        fill_uv(prim_id, u, v, si);
    finish_interaction(prim_id, u, v, with_uv, si);
}

}  // namespace render
