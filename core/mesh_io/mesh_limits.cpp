#include "core/mesh_io/mesh_limits.h"

#include "core/base/error.h"
#include "core/base/memory_budget.h"

namespace render {

uint64_t mesh_vertex_bytes(uint64_t vertices, bool normals, bool uvs) {
    const uint64_t per_vertex = 12 + (normals ? 12 : 0) + (uvs ? 8 : 0);
    return saturating_product(vertices, 2 * per_vertex);
}

uint64_t mesh_triangle_bytes(uint64_t triangles) {
    // Indices, Embree's closest-hit BVH, and the shadow rays' BVH (core/scene/scene.cpp:
    // 71 B per triangle measured on water-caustic's 102,938-triangle mesh).
    return saturating_product(triangles, 12 + 64 + 72);
}

void check_mesh_counts(const std::string& name, uint64_t vertices, uint64_t triangles) {
    if (vertices > kMaxMeshVertices)
        throw SceneError(name + ": " + std::to_string(vertices) + " vertices exceed the limit of " +
                         std::to_string(kMaxMeshVertices) + " (kMaxMeshVertices)");
    if (triangles > kMaxMeshTriangles)
        throw SceneError(name + ": " + std::to_string(triangles) +
                         " triangles exceed the limit of " + std::to_string(kMaxMeshTriangles) +
                         " (kMaxMeshTriangles)");
}

}  // namespace render
