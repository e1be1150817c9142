#pragma once

// Mitsuba's own mesh format (`.serialized`, the `serialized` shape), read with zlib. The format
// (Mitsuba 3's documentation of the plugin), all little-endian:
//   uint16 0x041C, uint16 version (3 or 4), then a zlib stream holding
//   uint32 flags (0x1 normals, 0x2 texture coordinates, 0x8 colours, 0x10 face normals,
//          0x1000 single precision, 0x2000 double precision),
//   (version 4 only) the shape's name, a null-terminated UTF-8 string,
//   uint64 vertex count, uint64 triangle count,
//   positions (xyz), normals (xyz, with 0x1), uv (with 0x2), colours (rgb, with 0x8) as float or
//   double, then 3 uint32 indices per triangle.
// Several meshes are concatenated (each with its own uncompressed 4-byte header); the file
// ends with the byte offset of each mesh (uint64 in version 4, uint32 in version 3) and a
// uint32 mesh count. Scene format reference: docs/reference/scene-format.md (shape `serialized`).

#include <cstddef>
#include <filesystem>
#include <string>
#include <string_view>

#include "core/shapes/triangle_mesh.h"

namespace render {

struct SerializedMesh {
    MeshData data;              // uv as stored (Mitsuba 3 does not flip them for this format)
    bool face_normals = false;  // the file's 0x10 flag
    std::string name;           // the shape's name (version 4), empty otherwise
};

// Mesh number `shape_index` of the file. Throws SceneError naming the file and what is wrong:
// a bad header or version, an index beyond the file's meshes, a broken dictionary, corrupt or
// truncated compressed data, counts the data cannot hold, more than 2^32 - 1 vertices.
// Vertex colours are read and dropped.
SerializedMesh read_serialized(const std::filesystem::path& path, size_t shape_index);

// The same from bytes in memory; `name` is used in messages.
SerializedMesh read_serialized_from_memory(std::string_view bytes, size_t shape_index,
                                           const std::string& name);

}  // namespace render
