#pragma once

// OpenVDB float grids (.vdb), through Debian's libopenvdb. Only this file's .cpp includes
// OpenVDB's headers (they are slow to compile).
//
// Reading densifies one float grid: the grid named "density" when the file has a float grid of
// that name, otherwise its first float grid. The dense array covers the grid's active voxel
// bounding box [imin, imax] (index space); voxel (i, j, k) of OpenVDB is centred on its index
// coordinates, so the array covers the index box [imin - 1/2, imax + 1/2], whose image under the
// grid's index-to-world transform (an axis-aligned box when the transform is a scale and
// translation; otherwise that box's bounding box) is `bbox`. This matches gridvolume's
// cell-centred convention: voxel centres sit at (i + 1/2) / res in the unit cube.

#include <string>

#include "core/media/vol_file.h"

namespace render {

// Throws SceneError("PATH: ...") for a missing or unreadable file, a file without float grids,
// an empty grid, or a grid too large to densify.
VolumeGridData read_vdb_file(const std::string& path);

// Writes `data` (1 channel) as a float grid named "density" whose voxel (i, j, k) is the array
// element (x, y, z) = (i, j, k), with an index-to-world transform mapping the array's voxel
// boxes onto data.bbox (a scale and translation). Every voxel of the array is stored as active
// (zeros included), so reading the file back yields the same array and bbox.
void write_vdb_file(const std::string& path, const VolumeGridData& data);

}  // namespace render
