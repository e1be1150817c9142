#pragma once

// Registry from scene-file shape names (rectangle, cube, sphere, disk, obj, ply, serialized,
// bsplinecurve, linearcurve) to shapes.
// Every parameter read here is listed in docs/reference/scene-format.md; keep the two in step.

#include <filesystem>
#include <memory>

#include "core/base/properties.h"
#include "core/base/shape.h"
#include "core/shapes/triangle_mesh.h"

namespace render {

// Builds the shape that props.type() names. Relative mesh file names resolve against
// `scene_dir`. Throws SceneError (file, line, field) for an unknown type, a missing mesh file,
// bad mesh data, a negative radius or a sphere transform that is not a similarity. The caller
// checks for unused parameters afterwards.
std::unique_ptr<Shape> make_shape(const Properties& props, const std::filesystem::path& scene_dir);

// Mitsuba 3's smooth vertex normals for a mesh that has none: the angle-weighted average of
// the adjacent face normals, computed in world space (to_world applied) and returned in object
// space so that TriangleMesh's inverse-transpose maps them back.
void compute_vertex_normals(MeshData& mesh, const Transform& to_world);

}  // namespace render
