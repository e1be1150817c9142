#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "core/base/shape.h"
#include "core/math/frame.h"
#include "core/math/transform.h"
#include "core/sampling/distribution.h"

namespace render {

// Raw triangle data as a file loader or a procedural generator produces it (object space).
struct MeshData {
    std::vector<Vec3> positions;
    std::vector<Vec3> normals;      // per vertex; empty = none
    std::vector<Vec2> uvs;          // per vertex; empty = none
    std::vector<uint32_t> indices;  // 3 per triangle
};

// Triangle mesh in world space. Shading uses the interpolated vertex normals unless the mesh
// has none or `face_normals` is set. Degenerate (zero-area) triangles are kept for
// intersection but never sampled.
class TriangleMesh final : public Shape {
  public:
    // Throws SceneError for out-of-range indices, non-finite positions or an index count that
    // is not a multiple of 3.
    TriangleMesh(MeshData data, const Transform& to_world, bool flip_normals, bool face_normals,
                 std::string name);

    unsigned attach(RTCDevice device, RTCScene scene) const override;
    void fill_interaction(const Ray& ray, float t, unsigned prim_id, float u, float v,
                          HitDetail detail, SurfaceInteraction& si) const override;
    // What fill_interaction does for a hit that needs no uv, on a mesh with hit records (below),
    // without the virtual call and without a test: defined inline in
    // core/shapes/triangle_mesh_hit.h for Scene::intersect, which calls it only for meshes
    // with has_hit_records() whose material does not vary.
    void fill_plain_hit(float t, unsigned prim_id, float u, float v, SurfaceInteraction& si) const;
    // Every triangle has a hit record (a flat-shaded mesh without degenerate triangles, within
    // kMaxHitRecordTriangles).
    bool has_hit_records() const { return frames_per_triangle_; }
    Aabb bounds() const override;
    float surface_area() const override { return area_; }
    ShapeSample sample_area(Vec2 u) const override;
    std::string to_string() const override;
    // By a search over the triangles: only for small meshes (rectangle, cube).
    bool has_uv_lookup() const override { return triangle_count() <= kMaxUvLookupTriangles; }
    Vec2 uv_at(const Vec3& p) const override;
    // By the hit's barycentrics, on a mesh of any size.
    Vec2 uv_at_hit(unsigned prim_id, Vec2 prim_uv, const Vec3&) const override {
        return uv_of(prim_id, prim_uv.x, prim_uv.y);
    }
    static constexpr size_t kMaxUvLookupTriangles = 64;

    size_t triangle_count() const { return indices_.size() / 3; }
    const std::vector<Vec3>& positions() const { return positions_; }

    const std::vector<uint32_t>& indices() const { return indices_; }
    // Unit geometric normal of triangle `tri` as hits report it (zero when degenerate).
    const Vec3& face_normal(size_t tri) const { return face_normals_[tri]; }
    // uv at barycentrics (b1, b2) of triangle `tri`, as a hit reports it.
    Vec2 uv_of(size_t tri, float b1, float b2) const;

    // Memory a flat-shaded mesh charges per triangle for its hit records (below).
    static constexpr size_t kHitRecordBytesPerTriangle = 96;

  private:
    // p, t, geometric normal and shading frame from the triangle's hit record.
    void fill_from_record(float t, unsigned prim_id, float u, float v,
                          SurfaceInteraction& si) const;
    // p, t, geometric normal and shading frame where the mesh has no frame per triangle
    // (interpolated vertex normals) or has degenerate triangles.
    [[gnu::noinline]] void fill_hit_interpolated(const Ray& ray, float t, unsigned prim_id, float u,
                                                 float v, SurfaceInteraction& si) const;
    // The hit's uv, dp/du and dp/dv.
    [[gnu::noinline]] void fill_uv(unsigned prim_id, float u, float v,
                                   SurfaceInteraction& si) const;
    // dp/du and dp/dv of triangle `tri` (constant over it; zero for degenerate uv).
    void tangents_of(size_t tri, Vec3& dpdu, Vec3& dpdv) const;
    // ng, or for a degenerate triangle (zero ng) the reverse ray direction (flipped if
    // flip_normals_). Out of line: only meshes with degenerate triangles call it.
    Vec3 facing_normal(const Vec3& ng, const Ray& ray) const;
    // Replaces normals_ by flat_frames_ if the mesh is flat-shaded; fills flat_frames_ from
    // the face normals of a mesh without vertex normals (up to kMaxFaceFrameTriangles).
    void keep_flat_frames();
    // A mesh shaded by its face normals keeps their frames up to this many triangles (144 KiB):
    // the frame copied at a hit instead of Frame::from_normal's ~35 instructions, without
    // adding 36 bytes per triangle to large meshes, whose hits miss the cache anyway.
    static constexpr size_t kMaxFaceFrameTriangles = 4096;

    std::vector<Vec3> positions_;
    // Unit geometric normal of each triangle (flipped if flip_normals_), zero for a degenerate
    // one: computed once here instead of at every hit (a cross product and a square root).
    std::vector<Vec3> face_normals_;
    bool has_degenerate_ = false;  // some face normal is zero (hits then face the ray)
    std::vector<Vec3> normals_;    // per vertex; empty when none or when flat_frames_ holds them
    // Shading frame of each triangle when every triangle's three vertex normals are equal (a
    // flat-shaded mesh such as the rectangle or the cube): a hit copies it instead of
    // interpolating three normals, renormalising (which gave the same normal up to rounding)
    // and building the frame. 36 bytes per triangle, what three unshared vertex normals take;
    // kept only where that is at most twice the vertex normals' memory. Also the frames of the
    // face normals of a small mesh without vertex normals (the same frames its hits built).
    // Empty otherwise.
    std::vector<Frame> flat_frames_;
    // flat_frames_ holds every triangle's frame and no triangle is degenerate: a hit copies
    // its frame and face normal (fill_from_record) from hit_records_.
    bool frames_per_triangle_ = false;
    // What fill_from_record reads of a triangle, in one place: its three vertices, each
    // padded to 16 bytes so that the hit point is interpolated with one SIMD load per vertex
    // and no index lookup (the same products and sums, in the same order, as the scalar
    // p0 b0 + p1 u + p2 v), then the face normal and frame in SurfaceInteraction's order (one
    // 48-byte copy). 96 bytes a triangle, kept up to kMaxHitRecordTriangles (6 MiB);
    // docs/results/performance-notes.md, "Closest hits through Scene::intersect".
    struct alignas(16) HitRecord {
        float p[3][4];
        Vec3 normal;
        Frame frame;
    };
    static_assert(sizeof(HitRecord) == kHitRecordBytesPerTriangle);
    static constexpr size_t kMaxHitRecordTriangles = size_t(1) << 16;
    std::vector<HitRecord> hit_records_;
    std::vector<Vec2> uvs_;
    std::vector<uint32_t> indices_;
    bool flip_normals_;
    float area_ = 0;
    Distribution1D triangle_distribution_;  // by area
    std::string name_;
};

// Procedural meshes with Mitsuba's object-space conventions.
MeshData make_rectangle_mesh();  // [-1,1]^2 at z = 0, normal +z, uv = ((x + 1) / 2, (y + 1) / 2)
MeshData make_cube_mesh();       // [-1,1]^3, outward normals, flat faces, each face's uv [0,1]^2

}  // namespace render
