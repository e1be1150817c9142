#include "core/mesh_io/serialized_reader.h"

#include <zlib.h>

#include <algorithm>
#include <bit>
#include <climits>
#include <cstdint>
#include <cstring>
#include <vector>

#include "core/base/error.h"
#include "core/mesh_io/file_bytes.h"

namespace render {
namespace {

// Values are copied from the little-endian file as they are.
static_assert(std::endian::native == std::endian::little, "a big-endian host needs byte swaps");

constexpr uint16_t kMagic = 0x041C;
constexpr uint32_t kHasNormals = 0x0001, kHasUvs = 0x0002, kHasColors = 0x0008,
                   kFaceNormals = 0x0010, kSingle = 0x1000, kDouble = 0x2000;
// DEFLATE cannot expand data by more than about 1032:1, so counts that need more bytes than
// that from what is left of the file are corrupt: refused before anything is allocated.
constexpr uint64_t kMaxDeflateRatio = 1032;
constexpr size_t kMaxNameLength = 4096;

uint64_t read_le(std::string_view bytes, size_t at, size_t size) {
    uint64_t value = 0;
    for (size_t i = 0; i < size; ++i)
        value |= uint64_t(static_cast<unsigned char>(bytes[at + i])) << (8 * i);
    return value;
}

// The zlib stream of one mesh, inflated on demand: never more than the reader asks for.
class Inflater {
  public:
    Inflater(std::string_view compressed, const std::string& file) : file_(file) {
        stream_.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(compressed.data()));
        remaining_in_ = compressed.size();
        feed();
        // 15 + 32: a zlib stream (Mitsuba's) or a gzip one, detected from its header.
        if (inflateInit2(&stream_, 15 + 32) != Z_OK)
            throw SceneError(file_ + ": cannot initialise zlib");
    }
    ~Inflater() { inflateEnd(&stream_); }
    Inflater(const Inflater&) = delete;
    Inflater& operator=(const Inflater&) = delete;

    // Exactly n bytes into `out`; `what` names them in the error for a short stream.
    void read(void* out, size_t n, const char* what) {
        auto* dst = static_cast<Bytef*>(out);
        while (n > 0) {
            const uInt chunk = uInt(std::min<size_t>(n, UINT_MAX));
            stream_.next_out = dst;
            stream_.avail_out = chunk;
            while (stream_.avail_out > 0) {
                feed();
                const uInt out_before = stream_.avail_out, in_before = stream_.avail_in;
                const int status = inflate(&stream_, Z_NO_FLUSH);
                if (status == Z_STREAM_END && stream_.avail_out > 0)
                    throw SceneError(file_ +
                                     ": truncated mesh: its compressed data ends inside "
                                     "the " +
                                     std::string(what));
                if (status != Z_OK && status != Z_STREAM_END && status != Z_BUF_ERROR)
                    throw SceneError(file_ + ": corrupt compressed data in the " +
                                     std::string(what) + " (zlib: " +
                                     (stream_.msg ? std::string(stream_.msg)
                                                  : "error " + std::to_string(status)) +
                                     ")");
                if (stream_.avail_out == out_before && stream_.avail_in == in_before &&
                    remaining_in_ == 0)
                    throw SceneError(file_ + ": truncated file: it ends inside the " +
                                     std::string(what));
            }
            dst += chunk;
            n -= chunk;
        }
    }

    // The stream must end here, its checksum (zlib's Adler-32 of the data) intact: catches
    // corruption that still inflates, and data the flags and counts do not account for.
    void finish() {
        unsigned char extra = 0;
        stream_.next_out = &extra;
        stream_.avail_out = 1;
        for (;;) {
            feed();
            const uInt in_before = stream_.avail_in;
            const int status = inflate(&stream_, Z_NO_FLUSH);
            if (status == Z_STREAM_END && stream_.avail_out == 1) return;
            if (stream_.avail_out == 0)
                throw SceneError(file_ +
                                 ": the compressed data holds more than its flags and "
                                 "counts describe");
            if (status != Z_OK && status != Z_BUF_ERROR)
                throw SceneError(
                    file_ + ": corrupt compressed data (zlib: " +
                    (stream_.msg ? std::string(stream_.msg) : "error " + std::to_string(status)) +
                    ")");
            if (stream_.avail_in == in_before && remaining_in_ == 0)
                throw SceneError(file_ +
                                 ": truncated file: it ends before the compressed "
                                 "data's checksum");
        }
    }

    // Bytes of compressed input not consumed yet.
    uint64_t compressed_left() const { return stream_.avail_in + remaining_in_; }

  private:
    // zlib counts input in 32-bit units: hand it the file in pieces.
    void feed() {
        if (stream_.avail_in > 0 || remaining_in_ == 0) return;
        const uInt chunk = uInt(std::min<uint64_t>(remaining_in_, UINT_MAX));
        stream_.avail_in = chunk;
        remaining_in_ -= chunk;
    }

    z_stream stream_{};
    uint64_t remaining_in_ = 0;
    std::string file_;
};

// n vectors of `dim` components (float or double in the file) as floats.
std::vector<float> read_reals(Inflater& in, uint64_t n, int dim, bool dbl, const char* what) {
    std::vector<float> out(size_t(n) * size_t(dim));
    if (!dbl) {
        in.read(out.data(), out.size() * sizeof(float), what);
        return out;
    }
    std::vector<double> chunk(std::min<size_t>(out.size(), 1 << 16));
    for (size_t done = 0; done < out.size(); done += chunk.size()) {
        const size_t count = std::min(chunk.size(), out.size() - done);
        in.read(chunk.data(), count * sizeof(double), what);
        for (size_t i = 0; i < count; ++i) out[done + i] = float(chunk[i]);
    }
    return out;
}

// The byte offset of mesh `index` from the end-of-file dictionary.
size_t mesh_offset(std::string_view bytes, uint16_t version, size_t index,
                   const std::string& file) {
    if (bytes.size() < 8)
        throw SceneError(file + ": shape_index " + std::to_string(index) +
                         ": the file is too short for a dictionary of meshes");
    const uint64_t count = read_le(bytes, bytes.size() - 4, 4);
    if (index >= count)
        throw SceneError(file + ": shape_index " + std::to_string(index) +
                         " is out of range: the file holds " + std::to_string(count) + " mesh(es)");
    const uint64_t entry = version == 4 ? 8 : 4;
    if (count * entry + 4 > bytes.size())
        throw SceneError(file + ": broken dictionary: " + std::to_string(count) +
                         " meshes do not fit in a file of " + std::to_string(bytes.size()) +
                         " bytes");
    const size_t at = bytes.size() - 4 - size_t((count - index) * entry);
    const uint64_t offset = read_le(bytes, at, size_t(entry));
    const uint64_t meshes_end = bytes.size() - 4 - count * entry;
    if (offset >= meshes_end || meshes_end - offset < 4)  // (offset + 4 could overflow)
        throw SceneError(file + ": broken dictionary: mesh " + std::to_string(index) +
                         " starts at byte " + std::to_string(offset) + ", beyond the meshes");
    return size_t(offset);
}

}  // namespace

SerializedMesh read_serialized_from_memory(std::string_view bytes, size_t shape_index,
                                           const std::string& name) {
    if (bytes.size() < 4) throw SceneError(name + ": too short for a serialized mesh header");
    if (read_le(bytes, 0, 2) != kMagic)
        throw SceneError(name +
                         ": not a Mitsuba serialized mesh (the file does not start with "
                         "0x041C)");
    const uint16_t version = uint16_t(read_le(bytes, 2, 2));
    if (version != 3 && version != 4)
        throw SceneError(name + ": serialized format version " + std::to_string(version) +
                         " is not supported (3 and 4 are)");
    size_t offset = 0;
    if (shape_index > 0) {
        offset = mesh_offset(bytes, version, shape_index, name);
        if (read_le(bytes, offset, 2) != kMagic || read_le(bytes, offset + 2, 2) != version)
            throw SceneError(name + ": broken dictionary: no mesh header at byte " +
                             std::to_string(offset) + " (mesh " + std::to_string(shape_index) +
                             ")");
    }
    const std::string where = name + " (mesh " + std::to_string(shape_index) + ")";
    Inflater in(bytes.substr(offset + 4), where);

    SerializedMesh mesh;
    uint32_t flags = 0;
    in.read(&flags, 4, "flags");
    if ((flags & kSingle) && (flags & kDouble))
        throw SceneError(where + ": flags say both single and double precision");
    const bool dbl = flags & kDouble;
    if (version == 4) {
        for (char c = 0;;) {
            in.read(&c, 1, "shape name");
            if (c == 0) break;
            if (mesh.name.size() >= kMaxNameLength)
                throw SceneError(where + ": the shape name is not terminated within " +
                                 std::to_string(kMaxNameLength) + " bytes");
            mesh.name += c;
        }
    }
    uint64_t vertex_count = 0, triangle_count = 0;
    in.read(&vertex_count, 8, "vertex count");
    in.read(&triangle_count, 8, "triangle count");
    if (vertex_count > UINT32_MAX)
        throw SceneError(where + ": " + std::to_string(vertex_count) +
                         " vertices: more than 2^32 - 1 are not supported");
    if (triangle_count > (uint64_t(1) << 40))
        throw SceneError(where + ": " + std::to_string(triangle_count) +
                         " triangles is not a plausible count");
    const uint64_t components = 3 + ((flags & kHasNormals) ? 3 : 0) + ((flags & kHasUvs) ? 2 : 0) +
                                ((flags & kHasColors) ? 3 : 0);
    const uint64_t needed = vertex_count * components * (dbl ? 8 : 4) + triangle_count * 12;
    if (needed > kMaxDeflateRatio * in.compressed_left() + 1024)
        throw SceneError(where + ": truncated or corrupt: " + std::to_string(vertex_count) +
                         " vertices and " + std::to_string(triangle_count) + " triangles need " +
                         std::to_string(needed) + " bytes, more than the " +
                         std::to_string(in.compressed_left()) + " compressed bytes left can hold");

    const std::vector<float> positions = read_reals(in, vertex_count, 3, dbl, "positions");
    mesh.data.positions.resize(size_t(vertex_count));
    for (size_t i = 0; i < mesh.data.positions.size(); ++i)
        mesh.data.positions[i] = Vec3(positions[3 * i], positions[3 * i + 1], positions[3 * i + 2]);
    if (flags & kHasNormals) {
        const std::vector<float> n = read_reals(in, vertex_count, 3, dbl, "normals");
        mesh.data.normals.resize(size_t(vertex_count));
        for (size_t i = 0; i < mesh.data.normals.size(); ++i)
            mesh.data.normals[i] = Vec3(n[3 * i], n[3 * i + 1], n[3 * i + 2]);
    }
    if (flags & kHasUvs) {
        const std::vector<float> uv = read_reals(in, vertex_count, 2, dbl, "texture coordinates");
        mesh.data.uvs.resize(size_t(vertex_count));
        for (size_t i = 0; i < mesh.data.uvs.size(); ++i)
            mesh.data.uvs[i] = Vec2(uv[2 * i], uv[2 * i + 1]);
    }
    if (flags & kHasColors) read_reals(in, vertex_count, 3, dbl, "vertex colours");
    mesh.data.indices.resize(size_t(triangle_count) * 3);
    in.read(mesh.data.indices.data(), mesh.data.indices.size() * 4, "triangle indices");
    in.finish();
    for (size_t i = 0; i < mesh.data.indices.size(); ++i)
        if (mesh.data.indices[i] >= vertex_count)
            throw SceneError(where + ": triangle " + std::to_string(i / 3) + ": vertex index " +
                             std::to_string(mesh.data.indices[i]) + " out of range (" +
                             std::to_string(vertex_count) + " vertices)");
    for (const Vec3& p : mesh.data.positions)
        if (!is_finite(p)) throw SceneError(where + ": a vertex position is not finite");
    mesh.face_normals = flags & kFaceNormals;
    return mesh;
}

SerializedMesh read_serialized(const std::filesystem::path& path, size_t shape_index) {
    const std::string bytes = read_file_bytes(path);
    return read_serialized_from_memory(bytes, shape_index, path.string());
}

}  // namespace render
