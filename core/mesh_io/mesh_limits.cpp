#include "core/mesh_io/mesh_limits.h"

#include "core/base/error.h"
#include "core/base/memory_budget.h"

namespace render {

uint64_t mesh_vertex_bytes(uint64_t vertices, bool normals, bool uvs) {
    const uint64_t per_vertex = 12 + (normals ? 12 : 0) + (uvs ? 8 : 0);
    return saturating_product(vertices, 2 * per_vertex);
}

uint64_t mesh_triangle_bytes(uint64_t triangles) {
    // Indices and Embree's closest-hit BVH. The shadow rays' BVH, built only for scenes of at
    // most Scene::kMaxShadowBvhTriangles, is charged by Scene::commit.
    return saturating_product(triangles, 12 + 64);
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
