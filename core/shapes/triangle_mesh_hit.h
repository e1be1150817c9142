#pragma once

// TriangleMesh::fill_hit, inline so that Scene::intersect fills a mesh hit without a virtual
// call and a call frame (docs/results/performance-notes.md, "Closest hits through
// Scene::intersect").

#include "core/shapes/triangle_mesh.h"
#include "core/shapes/uv_wanted.h"

namespace render {

inline void TriangleMesh::fill_hit(const Ray& ray, float t, unsigned prim_id, float u, float v,
                                   HitDetail detail, SurfaceInteraction& si) const {
    const uint32_t* index = &indices_[3 * size_t(prim_id)];
    const uint32_t i0 = index[0], i1 = index[1], i2 = index[2];
    const Vec3 &p0 = positions_[i0], &p1 = positions_[i1], &p2 = positions_[i2];
    const float b0 = 1.0f - u - v;
    // Interpolating the vertices is more accurate than origin + t * direction far from the
    // ray origin.
    si.p = p0 * b0 + p1 * u + p2 * v;
    si.t = t;
    Vec3 ng = face_normals_[prim_id];
    if (has_degenerate_) [[unlikely]]
        ng = facing_normal(ng, ray);
    si.geometric_normal = ng;

    if (!flat_frames_.empty()) {
        si.shading = flat_frames_[prim_id];
    } else {
        Vec3 ns = ng;
        if (!normals_.empty()) {
            const Vec3 n = normals_[i0] * b0 + normals_[i1] * u + normals_[i2] * v;
            const float nlen = length(n);
            if (nlen > 0 && std::isfinite(nlen)) {
                ns = n / nlen;
                if (flip_normals_) ns = -ns;
            }
        }
        si.shading = Frame::from_normal(ns);
    }
    if (uv_wanted(*this, detail)) {
        si.uv = uv_of(prim_id, u, v);
        tangents_of(prim_id, si.dpdu, si.dpdv);
    } else {
        si.uv = Vec2();
        si.dpdu = si.dpdv = Vec3(0.0f);
    }
    si.shape = this;
    si.bsdf = bsdf;
    si.emitter = emitter;
}

}  // namespace render
