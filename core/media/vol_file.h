#pragma once

// Mitsuba's binary volume format (.vol, shared by Mitsuba 0.6, 2 and 3), little-endian:
//
//   bytes  0-2   'V' 'O' 'L'
//   byte   3     version (3)
//   bytes  4-7   encoding, int32 (1 = float32, the only one supported)
//   bytes  8-19  xres, yres, zres, int32
//   bytes 20-23  channels, int32 (1 or 3 here; Mitsuba also has 6)
//   bytes 24-47  bounding box, 6 float32: xmin, ymin, zmin, xmax, ymax, zmax
//   bytes 48-    xres * yres * zres * channels float32,
//                data[((z * yres + y) * xres + x) * channels + c]   (x fastest)
//
// Mitsuba 3's gridvolume ignores the bounding box unless `use_grid_bbox` is set: the grid fills
// the unit cube [0,1]^3, which `to_world` places in the scene.

#include <cstddef>
#include <string>
#include <vector>

#include "core/base/shape.h"

namespace render {

// A dense grid of voxel values, x fastest, channels interleaved.
struct VolumeGridData {
    int xres = 0, yres = 0, zres = 0, channels = 1;
    // The data's bounding box in world units (the .vol header's, or the .vdb grid's).
    Aabb bbox;
    std::vector<float> values;

    size_t voxel_count() const { return size_t(xres) * size_t(yres) * size_t(zres); }
    float at(int x, int y, int z, int c) const {
        return values[((size_t(z) * size_t(yres) + size_t(y)) * size_t(xres) + size_t(x)) *
                          size_t(channels) +
                      size_t(c)];
    }
};

// Largest grid accepted (voxels times channels): 2^30 floats = 4 GiB.
inline constexpr size_t kMaxVolumeValues = size_t(1) << 30;

// Reads and validates a .vol file: header, version, encoding, sizes (at least 1 voxel per axis,
// channels 1 or 3), exact file length. Throws SceneError("PATH: ...") on any problem; never
// reads past the file or allocates more than the file holds. Values are not checked here (see
// check_volume_values).
VolumeGridData read_vol_file(const std::string& path);

// Parses .vol bytes already in memory; `name` labels error messages.
VolumeGridData parse_vol(const std::vector<unsigned char>& bytes, const std::string& name);

// Writes a .vol file (version 3, float32). Throws SceneError when the file cannot be written or
// the data is inconsistent.
void write_vol_file(const std::string& path, const VolumeGridData& data);

// Throws SceneError("NAME: ...") naming the first NaN, infinite or negative value.
void check_volume_values(const VolumeGridData& data, const std::string& name);

}  // namespace render
