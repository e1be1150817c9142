#pragma once

// A small PLY reader (there is no Debian PLY library): ASCII, binary_little_endian and
// binary_big_endian files. Reads the `vertex` element's x y z, optional nx ny nz and texture
// coordinates (u v, s t, texture_u texture_v or texture_s texture_t), and the `face` element's
// index list (`vertex_indices` or `vertex_index`, any integer count and index type). Polygons
// are fan-triangulated. Other elements and properties are read and ignored.
// Scene format reference: docs/reference/scene-format.md (shape `ply`).

#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include "core/shapes/triangle_mesh.h"

namespace render {

// A four-sided face of the file: its vertices in the file's order and the index of the first of
// the two triangles the fan made of it in MeshData::indices (triangles first_triangle and
// first_triangle + 1: (v0, v1, v2) and (v0, v2, v3)). pbrt-v4 reads such faces as bilinear
// patches (docs/reference/scene-format.md, "pbrt-v4 scenes").
struct PlyQuad {
    uint32_t v[4];
    size_t first_triangle;
};

// Throws SceneError naming the file and the header line or element (e.g. "face 12") for bad
// input: unknown format, malformed header, truncated data, out-of-range indices, non-finite
// positions. With `quads`, the file's four-sided faces are also listed there (the mesh is the
// same either way).
MeshData read_ply(const std::filesystem::path& path, std::vector<PlyQuad>* quads = nullptr);

// The same from bytes in memory; `name` is used in messages.
MeshData read_ply_from_memory(std::string_view bytes, const std::string& name,
                              std::vector<PlyQuad>* quads = nullptr);

}  // namespace render
