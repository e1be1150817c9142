#include "core/shapes/triangle_mesh.h"

#include <cmath>
#include <sstream>

#include "core/base/error.h"
#include "core/base/memory_budget.h"
#include "core/sampling/warp.h"
#include "core/shapes/alpha_cutout.h"
#include "core/shapes/triangle_mesh_hit.h"
#include "core/shapes/uv_wanted.h"

namespace render {
namespace {

// Embree's filter for meshes with a cut-out: rejects the candidate hits the cut-out drops.
void alpha_filter(const RTCFilterFunctionNArguments* args) {
    const auto* mesh = static_cast<const TriangleMesh*>(args->geometryUserPtr);
    for (unsigned i = 0; i < args->N; ++i) {
        if (args->valid[i] != -1) continue;
        const float org[3] = {RTCRayN_org_x(args->ray, args->N, i),
                              RTCRayN_org_y(args->ray, args->N, i),
                              RTCRayN_org_z(args->ray, args->N, i)};
        const float dir[3] = {RTCRayN_dir_x(args->ray, args->N, i),
                              RTCRayN_dir_y(args->ray, args->N, i),
                              RTCRayN_dir_z(args->ray, args->N, i)};
        const Vec2 uv =
            mesh->uv_of(RTCHitN_primID(args->hit, args->N, i), RTCHitN_u(args->hit, args->N, i),
                        RTCHitN_v(args->hit, args->N, i));
        if (!mesh->alpha->keeps_hit(uv, org, dir, RTCRayN_tfar(args->ray, args->N, i)))
            args->valid[i] = 0;
    }
}

}  // namespace

TriangleMesh::TriangleMesh(MeshData data, const Transform& to_world, bool flip_normals,
                           bool face_normals, std::string name)
    : flip_normals_(flip_normals), name_(std::move(name)) {
    if (data.indices.size() % 3 != 0)
        throw SceneError(name_ + ": index count " + std::to_string(data.indices.size()) +
                         " is not a multiple of 3");
    for (uint32_t index : data.indices)
        if (index >= data.positions.size())
            throw SceneError(name_ + ": vertex index " + std::to_string(index) +
                             " out of range (the mesh has " +
                             std::to_string(data.positions.size()) + " vertices)");
    if (to_world.is_singular()) throw SceneError(name_ + ": to_world transform is singular");

    positions_.reserve(data.positions.size());
    for (const Vec3& p : data.positions) {
        Vec3 w = to_world.apply_point(p);
        if (!is_finite(w)) throw SceneError(name_ + ": non-finite vertex position");
        positions_.push_back(w);
    }
    if (!face_normals && data.normals.size() == data.positions.size()) {
        normals_.reserve(data.normals.size());
        for (const Vec3& n : data.normals) {
            Vec3 w = to_world.apply_normal(n);
            float len = length(w);
            // A zero or broken normal falls back to the face normal at shading time.
            normals_.push_back(len > 0 && std::isfinite(len) ? w / len : Vec3(0.0f));
        }
    }
    if (data.uvs.size() == data.positions.size()) uvs_ = std::move(data.uvs);
    indices_ = std::move(data.indices);

    // A mirroring transform reverses the winding, so the face normal would disagree with the
    // transformed normal (inverse transpose of the object normal, which Mitsuba's rectangle
    // uses). Reversing the triangles keeps both on the same side, as pbrt does.
    if (to_world.determinant3x3() < 0)
        for (size_t i = 0; i + 2 < indices_.size(); i += 3)
            std::swap(indices_[i + 1], indices_[i + 2]);
    std::vector<float> areas(triangle_count());
    face_normals_.resize(triangle_count());
    double total = 0;
    for (size_t i = 0; i < triangle_count(); ++i) {
        const Vec3& p0 = positions_[indices_[3 * i]];
        const Vec3& p1 = positions_[indices_[3 * i + 1]];
        const Vec3& p2 = positions_[indices_[3 * i + 2]];
        const Vec3 ng = cross(p1 - p0, p2 - p0);
        const float len = length(ng);
        if (len > 0) face_normals_[i] = flip_normals_ ? -(ng / len) : ng / len;
        const Vec3& n = face_normals_[i];
        if (n.x == 0 && n.y == 0 && n.z == 0) has_degenerate_ = true;
        float a = 0.5f * len;
        areas[i] = std::isfinite(a) ? a : 0.0f;
        total += areas[i];
    }
    area_ = float(total);
    triangle_distribution_ = Distribution1D(std::move(areas));
    keep_flat_frames();
    frames_per_triangle_ =
        !flat_frames_.empty() && !has_degenerate_ && triangle_count() <= kMaxHitRecordTriangles;
    if (frames_per_triangle_) {
        // The worker's memory budget (docs/guide/reliability.md, "The memory budget").
        charge_scene_memory(triangle_count() * sizeof(HitRecord), name_ + ": hit records");
        hit_records_.resize(triangle_count());
        for (size_t i = 0; i < triangle_count(); ++i) {
            HitRecord& r = hit_records_[i];
            for (int k = 0; k < 3; ++k) {
                const Vec3& p = positions_[indices_[3 * i + size_t(k)]];
                r.p[k][0] = p.x, r.p[k][1] = p.y, r.p[k][2] = p.z, r.p[k][3] = 0;
            }
            r.normal = face_normals_[i];
            r.frame = flat_frames_[i];
        }
    }
}

void TriangleMesh::keep_flat_frames() {
    if (normals_.empty()) {
        // Shaded by the face normal: the frame a hit would build from it, built here once. Not
        // with degenerate triangles, whose hits build theirs from the ray (facing_normal).
        if (has_degenerate_ || triangle_count() > kMaxFaceFrameTriangles) return;
        flat_frames_.resize(triangle_count());
        for (size_t i = 0; i < triangle_count(); ++i)
            flat_frames_[i] = Frame::from_normal(face_normals_[i]);
        return;
    }
    // At most twice the memory of the vertex normals they replace (equal for unshared vertices,
    // 1.5x for the rectangle and the cube; a finely tessellated plane would take 6x).
    if (triangle_count() * sizeof(Frame) > 2 * normals_.size() * sizeof(Vec3)) return;
    std::vector<Frame> frames(triangle_count());
    for (size_t i = 0; i < triangle_count(); ++i) {
        const Vec3& n = normals_[indices_[3 * i]];
        if (!(n == normals_[indices_[3 * i + 1]] && n == normals_[indices_[3 * i + 2]]) ||
            length_squared(n) == 0)
            return;  // smooth somewhere (or a broken normal): interpolate at every hit
        frames[i] = Frame::from_normal(flip_normals_ ? -n : n);
    }
    flat_frames_ = std::move(frames);
    normals_ = {};
}

unsigned TriangleMesh::attach(RTCDevice device, RTCScene scene) const {
    RTCGeometry geometry = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
    // Embree reads vertices as 16-byte loads; rtcSetNewGeometryBuffer pads the buffer for it.
    auto* vertices = static_cast<float*>(
        rtcSetNewGeometryBuffer(geometry, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                3 * sizeof(float), positions_.size()));
    for (size_t i = 0; i < positions_.size(); ++i) {
        vertices[3 * i] = positions_[i].x;
        vertices[3 * i + 1] = positions_[i].y;
        vertices[3 * i + 2] = positions_[i].z;
    }
    auto* indices = static_cast<uint32_t*>(
        rtcSetNewGeometryBuffer(geometry, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                3 * sizeof(uint32_t), triangle_count()));
    std::copy(indices_.begin(), indices_.end(), indices);
    if (alpha) {
        // Cut-outs: Embree asks the filter about every candidate hit, for both query kinds.
        rtcSetGeometryUserData(geometry, const_cast<TriangleMesh*>(this));
        rtcSetGeometryIntersectFilterFunction(geometry, alpha_filter);
        rtcSetGeometryOccludedFilterFunction(geometry, alpha_filter);
    }
    rtcCommitGeometry(geometry);
    unsigned id = rtcAttachGeometry(scene, geometry);
    rtcReleaseGeometry(geometry);
    return id;
}

void TriangleMesh::fill_interaction(const Ray& ray, float t, unsigned prim_id, float u, float v,
                                    HitDetail detail, SurfaceInteraction& si) const {
    if (frames_per_triangle_)
        fill_from_record(t, prim_id, u, v, si);
    else
        fill_hit_interpolated(ray, t, prim_id, u, v, si);
    const bool with_uv = uv_wanted(*this, detail);
    if (with_uv) fill_uv(prim_id, u, v, si);
    finish_interaction(prim_id, u, v, with_uv, si);
}

void TriangleMesh::fill_hit_interpolated(const Ray& ray, float t, unsigned prim_id, float u,
                                         float v, SurfaceInteraction& si) const {
    const uint32_t* index = &indices_[3 * size_t(prim_id)];
    const uint32_t i0 = index[0], i1 = index[1], i2 = index[2];
    const Vec3 &p0 = positions_[i0], &p1 = positions_[i1], &p2 = positions_[i2];
    const float b0 = 1.0f - u - v;
    si.p = p0 * b0 + p1 * u + p2 * v;
    si.t = t;
    Vec3 ng = face_normals_[prim_id];
    if (has_degenerate_) ng = facing_normal(ng, ray);
    si.geometric_normal = ng;
    if (!flat_frames_.empty()) {
        si.shading = flat_frames_[prim_id];
        return;
    }
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

void TriangleMesh::fill_uv(unsigned prim_id, float u, float v, SurfaceInteraction& si) const {
    si.uv = uv_of(prim_id, u, v);
    tangents_of(prim_id, si.dpdu, si.dpdv);
}

Vec3 TriangleMesh::facing_normal(const Vec3& ng, const Ray& ray) const {
    if (ng.x != 0 || ng.y != 0 || ng.z != 0) return ng;
    return flip_normals_ ? ray.direction : ray.direction * -1.0f;
}

void TriangleMesh::tangents_of(size_t tri, Vec3& dpdu, Vec3& dpdv) const {
    const uint32_t* i = &indices_[3 * tri];
    const Vec3 e1 = positions_[i[1]] - positions_[i[0]], e2 = positions_[i[2]] - positions_[i[0]];
    if (uvs_.empty()) {  // uv = (b1, b2): p = p0 + u e1 + v e2
        dpdu = e1;
        dpdv = e2;
        return;
    }
    // Solve e1 = dpdu du1 + dpdv dv1, e2 = dpdu du2 + dpdv dv2.
    const Vec2 d1 = uvs_[i[1]] - uvs_[i[0]], d2 = uvs_[i[2]] - uvs_[i[0]];
    const float det = d1.x * d2.y - d1.y * d2.x;
    dpdu = dpdv = Vec3(0.0f);
    if (!(std::abs(det) > 0)) return;  // degenerate uv: no tangents
    const Vec3 u = (e1 * d2.y - e2 * d1.y) / det, v = (e2 * d1.x - e1 * d2.x) / det;
    if (is_finite(u)) dpdu = u;
    if (is_finite(v)) dpdv = v;
}

Vec2 TriangleMesh::uv_of(size_t tri, float b1, float b2) const {
    if (uvs_.empty()) return Vec2(b1, b2);
    const uint32_t* i = &indices_[3 * tri];
    return uvs_[i[0]] * (1.0f - b1 - b2) + uvs_[i[1]] * b1 + uvs_[i[2]] * b2;
}

Vec2 TriangleMesh::uv_at(const Vec3& p) const {
    // The triangle whose plane passes nearest to p among those whose barycentrics of p's
    // projection are inside (with a margin for rounding).
    float best = kInfinity;
    Vec2 uv;
    for (size_t tri = 0; tri < triangle_count(); ++tri) {
        const Vec3& p0 = positions_[indices_[3 * tri]];
        const Vec3 e1 = positions_[indices_[3 * tri + 1]] - p0;
        const Vec3 e2 = positions_[indices_[3 * tri + 2]] - p0;
        const Vec3 n = cross(e1, e2);
        const float n2 = length_squared(n);
        if (!(n2 > 0)) continue;
        const Vec3 d = p - p0;
        const float b1 = dot(cross(d, e2), n) / n2;
        const float b2 = dot(cross(e1, d), n) / n2;
        const float margin = 1e-4f;
        if (b1 < -margin || b2 < -margin || b1 + b2 > 1 + margin) continue;
        const float distance = std::abs(dot(d, n)) / std::sqrt(n2);
        if (distance < best) best = distance, uv = uv_of(tri, b1, b2);
    }
    return uv;
}

Aabb TriangleMesh::bounds() const {
    Aabb box;
    for (const Vec3& p : positions_) box.expand(p);
    return box;
}

ShapeSample TriangleMesh::sample_area(Vec2 u) const {
    ShapeSample s;
    if (area_ <= 0) return s;
    float u_remapped;
    size_t tri = triangle_distribution_.sample_discrete(u.x, nullptr, &u_remapped);
    Vec2 b = warp::square_to_uniform_triangle(Vec2(u_remapped, u.y));
    const Vec3& p0 = positions_[indices_[3 * tri]];
    const Vec3& p1 = positions_[indices_[3 * tri + 1]];
    const Vec3& p2 = positions_[indices_[3 * tri + 2]];
    s.p = p0 * (1.0f - b.x - b.y) + p1 * b.x + p2 * b.y;
    Vec3 n = normalize(cross(p1 - p0, p2 - p0));
    s.n = flip_normals_ ? -n : n;
    s.uv = uv_of(tri, b.x, b.y);
    s.pdf_area = 1.0f / area_;
    return s;
}

std::string TriangleMesh::to_string() const {
    std::ostringstream out;
    out << "TriangleMesh[" << name_ << ", " << triangle_count() << " triangles, area " << area_
        << "]";
    return out.str();
}

MeshData make_rectangle_mesh() {
    MeshData m;
    m.positions = {{-1, -1, 0}, {1, -1, 0}, {1, 1, 0}, {-1, 1, 0}};
    m.normals = {{0, 0, 1}, {0, 0, 1}, {0, 0, 1}, {0, 0, 1}};
    m.uvs = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
    m.indices = {0, 1, 2, 0, 2, 3};
    return m;
}

MeshData make_cube_mesh() {
    // Six faces with their own vertices so that normals stay flat.
    MeshData m;
    const Vec3 normals[6] = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
    // Mitsuba's uv layout: on each face u = (a . p + 1) / 2 and v = (b . p + 1) / 2.
    const Vec3 u_axes[6] = {{0, 1, 0}, {0, 1, 0}, {-1, 0, 0}, {0, 0, 1}, {0, 1, 0}, {0, -1, 0}};
    const Vec3 v_axes[6] = {{0, 0, -1}, {0, 0, 1}, {0, 0, -1}, {1, 0, 0}, {1, 0, 0}, {1, 0, 0}};
    for (int face = 0; face < 6; ++face) {
        const Vec3& n = normals[face];
        // Two tangents with cross(s, t) = n so the winding faces outward.
        Vec3 s = std::abs(n.x) > 0 ? Vec3(0, 1, 0) : Vec3(1, 0, 0);
        Vec3 t = cross(n, s);
        uint32_t base = uint32_t(m.positions.size());
        const float corners[4][2] = {{-1, -1}, {1, -1}, {1, 1}, {-1, 1}};
        for (const auto& c : corners) {
            const Vec3 p = n + s * c[0] + t * c[1];
            m.positions.push_back(p);
            m.normals.push_back(n);
            m.uvs.push_back(
                Vec2(0.5f * (dot(u_axes[face], p) + 1), 0.5f * (dot(v_axes[face], p) + 1)));
        }
        m.indices.insert(m.indices.end(), {base, base + 1, base + 2, base, base + 2, base + 3});
    }
    return m;
}

}  // namespace render
