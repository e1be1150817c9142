#pragma once

// The largest mesh a scene may hold, and the memory a mesh is estimated to take, shared by the
// mesh readers (PLY, OBJ) and the scene formats' inline meshes. The readers check the counts a
// file announces against these before allocating (and against the file's size: a count the
// data cannot hold is never allocated).

#include <cstdint>
#include <string>

namespace render {

// 2^28 vertices or triangles: 8.6 GiB of positions, normals and texture coordinates, or
// about 20 GiB of triangles with their index and acceleration structure. Larger meshes are
// refused rather than left to exhaust a worker.
inline constexpr uint64_t kMaxMeshVertices = uint64_t(1) << 28;
inline constexpr uint64_t kMaxMeshTriangles = uint64_t(1) << 28;

// Estimated bytes of `vertices` vertices (position, and normal and texture coordinates if
// present, kept twice: as read and in world space) and of `triangles` triangles (three 32-bit
// indices and about 64 bytes of Embree's closest-hit acceleration structure each; a small
// scene's shadow-ray BVH is charged by Scene::commit).
uint64_t mesh_vertex_bytes(uint64_t vertices, bool normals, bool uvs);
uint64_t mesh_triangle_bytes(uint64_t triangles);

// Throws SceneError "NAME: COUNT vertices exceed the limit of 268435456 (kMaxMeshVertices)"
// (the same for triangles) when a count is past its limit.
void check_mesh_counts(const std::string& name, uint64_t vertices, uint64_t triangles);

}  // namespace render
