#pragma once

// A Wavefront OBJ reader: `v`, `vn`, `vt` and `f` (all index forms: i, i/t, i//n, i/t/n, with
// negative indices counting back from the last element defined so far). Polygons are
// fan-triangulated; other statements (o, g, s, usemtl, mtllib, l, p, ...) are ignored.
// Every distinct (position, uv, normal) index triple becomes one output vertex. Normals (uvs)
// are kept only if every face vertex references one.
// Scene format reference: docs/reference/scene-format.md (shape `obj`).

#include <filesystem>
#include <string>
#include <string_view>

#include "core/shapes/triangle_mesh.h"

namespace render {

// Throws SceneError naming the file and line for bad input (unparsable numbers, non-finite
// values, index 0 or out of range, faces with fewer than 3 vertices).
MeshData read_obj(const std::filesystem::path& path);

// The same from text in memory; `name` is used in messages.
MeshData read_obj_from_memory(std::string_view text, const std::string& name);

}  // namespace render
