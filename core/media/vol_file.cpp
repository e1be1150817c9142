#include "core/media/vol_file.h"

#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <sstream>

#include "core/base/error.h"
#include "core/base/memory_budget.h"

namespace render {
namespace {

constexpr size_t kHeaderSize = 48;

// Little-endian decoding independent of the host's byte order.
uint32_t read_u32(const unsigned char* p) {
    return uint32_t(p[0]) | (uint32_t(p[1]) << 8) | (uint32_t(p[2]) << 16) | (uint32_t(p[3]) << 24);
}
int32_t read_i32(const unsigned char* p) {
    uint32_t u = read_u32(p);
    int32_t i;
    std::memcpy(&i, &u, 4);
    return i;
}
float read_f32(const unsigned char* p) {
    uint32_t u = read_u32(p);
    float f;
    std::memcpy(&f, &u, 4);
    return f;
}
void write_u32(std::vector<unsigned char>& out, uint32_t u) {
    for (int i = 0; i < 4; ++i) out.push_back((unsigned char)((u >> (8 * i)) & 0xffu));
}
void write_i32(std::vector<unsigned char>& out, int32_t i) {
    uint32_t u;
    std::memcpy(&u, &i, 4);
    write_u32(out, u);
}
void write_f32(std::vector<unsigned char>& out, float f) {
    uint32_t u;
    std::memcpy(&u, &f, 4);
    write_u32(out, u);
}

SceneError error(const std::string& name, const std::string& message) {
    return SceneError(name + ": " + message);
}

// Validates the 48-byte header against the total length `size` and returns the grid without
// its values.
VolumeGridData parse_header(const unsigned char* bytes, size_t size, const std::string& name) {
    if (size < kHeaderSize)
        throw error(name, "not a volume file: " + std::to_string(size) +
                              " bytes, shorter than the 48-byte .vol header");
    if (bytes[0] != 'V' || bytes[1] != 'O' || bytes[2] != 'L')
        throw error(name, "not a .vol file (the header does not start with \"VOL\")");
    if (bytes[3] != 3)
        throw error(name, "unsupported .vol version " + std::to_string(int(bytes[3])) +
                              " (only version 3 is supported)");
    const int32_t encoding = read_i32(&bytes[4]);
    if (encoding != 1)
        throw error(name, "unsupported .vol encoding " + std::to_string(encoding) +
                              " (only 1 = float32 is supported)");
    VolumeGridData d;
    d.xres = read_i32(&bytes[8]);
    d.yres = read_i32(&bytes[12]);
    d.zres = read_i32(&bytes[16]);
    d.channels = read_i32(&bytes[20]);
    if (d.xres < 1 || d.yres < 1 || d.zres < 1) {
        std::ostringstream os;
        os << "invalid grid size " << d.xres << " x " << d.yres << " x " << d.zres
           << " (each must be at least 1)";
        throw error(name, os.str());
    }
    if (d.channels != 1 && d.channels != 3)
        throw error(name, "unsupported channel count " + std::to_string(d.channels) +
                              " (1 or 3 are supported)");
    // Overflow-safe size: every factor is below 2^31; check against the limit step by step.
    size_t count = size_t(d.channels);
    for (int r : {d.xres, d.yres, d.zres}) {
        if (count > kMaxVolumeValues / size_t(r)) {
            std::ostringstream os;
            os << "grid " << d.xres << " x " << d.yres << " x " << d.zres << " x " << d.channels
               << " is too large (more than 2^30 values)";
            throw error(name, os.str());
        }
        count *= size_t(r);
    }
    const size_t expected = kHeaderSize + 4 * count;
    if (size != expected) {
        std::ostringstream os;
        os << (size < expected ? "truncated" : "has trailing data") << ": a " << d.xres << " x "
           << d.yres << " x " << d.zres << " grid with " << d.channels << " channel(s) needs "
           << expected << " bytes, the file has " << size;
        throw error(name, os.str());
    }
    // Read as a body of bytes, then decoded to floats: twice the values.
    charge_scene_memory(8 * count, name + ": grid values");
    float box[6];
    for (int i = 0; i < 6; ++i) box[i] = read_f32(&bytes[24 + 4 * size_t(i)]);
    d.bbox.lo = Vec3(box[0], box[1], box[2]);
    d.bbox.hi = Vec3(box[3], box[4], box[5]);
    return d;
}

void decode_values(const unsigned char* bytes, VolumeGridData& d) {
    d.values.resize(d.voxel_count() * size_t(d.channels));
    for (size_t i = 0; i < d.values.size(); ++i) d.values[i] = read_f32(bytes + 4 * i);
}

}  // namespace

VolumeGridData parse_vol(const std::vector<unsigned char>& bytes, const std::string& name) {
    VolumeGridData d = parse_header(bytes.data(), bytes.size(), name);
    decode_values(bytes.data() + kHeaderSize, d);
    return d;
}

VolumeGridData read_vol_file(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw error(path, "cannot open volume file");
    in.seekg(0, std::ios::end);
    const std::streamoff size = in.tellg();
    if (size < 0) throw error(path, "cannot read volume file");
    in.seekg(0, std::ios::beg);
    // The header is checked against the file length before anything else is allocated.
    unsigned char header[kHeaderSize] = {};
    const size_t header_bytes = std::min(size_t(size), kHeaderSize);
    in.read(reinterpret_cast<char*>(header), std::streamsize(header_bytes));
    if (!in) throw error(path, "cannot read volume file");
    VolumeGridData d = parse_header(header, size_t(size), path);
    std::vector<unsigned char> body(size_t(size) - kHeaderSize);
    in.read(reinterpret_cast<char*>(body.data()), std::streamsize(body.size()));
    if (!in) throw error(path, "cannot read volume file");
    decode_values(body.data(), d);
    return d;
}

void write_vol_file(const std::string& path, const VolumeGridData& data) {
    if (data.xres < 1 || data.yres < 1 || data.zres < 1 ||
        (data.channels != 1 && data.channels != 3) ||
        data.values.size() != data.voxel_count() * size_t(data.channels))
        throw error(path, "inconsistent volume data (size or channel count)");
    std::vector<unsigned char> out;
    out.reserve(kHeaderSize + 4 * data.values.size());
    out.push_back('V');
    out.push_back('O');
    out.push_back('L');
    out.push_back(3);
    write_i32(out, 1);
    write_i32(out, data.xres);
    write_i32(out, data.yres);
    write_i32(out, data.zres);
    write_i32(out, data.channels);
    for (const Vec3& v : {data.bbox.lo, data.bbox.hi})
        for (int i = 0; i < 3; ++i) write_f32(out, v[i]);
    for (float v : data.values) write_f32(out, v);
    std::ofstream f(path, std::ios::binary | std::ios::trunc);
    if (!f) throw error(path, "cannot create volume file");
    f.write(reinterpret_cast<const char*>(out.data()), std::streamsize(out.size()));
    f.close();
    if (!f) throw error(path, "cannot write volume file");
}

void check_volume_values(const VolumeGridData& data, const std::string& name) {
    for (size_t i = 0; i < data.values.size(); ++i) {
        const float v = data.values[i];
        if (std::isfinite(v) && v >= 0) continue;
        const size_t voxel = i / size_t(data.channels);
        const size_t x = voxel % size_t(data.xres),
                     y = voxel / size_t(data.xres) % size_t(data.yres),
                     z = voxel / (size_t(data.xres) * size_t(data.yres));
        std::ostringstream os;
        os << (std::isnan(v) ? "NaN" : (std::isinf(v) ? "infinite" : "negative")) << " value " << v
           << " at voxel (" << x << ", " << y << ", " << z << ")";
        if (data.channels > 1) os << ", channel " << i % size_t(data.channels);
        os << "; volume values must be finite and non-negative";
        throw error(name, os.str());
    }
}

}  // namespace render
