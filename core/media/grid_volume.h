#pragma once

// Mitsuba 3's `gridvolume`: a dense voxel grid (from a .vol or .vdb file) filling the unit cube
// [0,1]^3 of its local space, which `to_world` places in the scene (the file's own bounding box
// is ignored unless `use_grid_bbox` is set, as in Mitsuba 3).
//
// Interpolation follows Mitsuba 3 (Dr.Jit's Texture3f, wrap mode `clamp`): values are
// *cell-centred*. With res voxels along an axis, voxel i is centred at (i + 1/2) / res; a local
// coordinate u is looked up at x = u * res - 1/2, between voxels floor(x) and floor(x) + 1 with
// weight x - floor(x), indices clamped to [0, res - 1] (so within half a voxel of a face the
// value is the face voxel's, not fading to zero). `nearest` takes voxel clamp(floor(u * res)).
// Outside the unit cube the value is 0.

#include <memory>
#include <vector>

#include "core/math/transform.h"
#include "core/media/vol_file.h"
#include "core/media/volume.h"

namespace render {

enum class VolumeFilter { kTrilinear, kNearest };

class GridVolume final : public Volume {
  public:
    // `data` must be consistent (sizes, 1 or 3 channels) with finite non-negative values;
    // `to_world` maps the unit cube to world space and must be invertible.
    GridVolume(VolumeGridData data, const Transform& to_world,
               VolumeFilter filter = VolumeFilter::kTrilinear, std::string name = "");

    Rgb eval(const Vec3& p) const override;
    float max_value() const override { return max_; }
    float max_in(const Aabb& world_box) const override;
    Aabb bounds() const override { return bounds_; }
    int channels() const override { return data_.channels; }
    std::array<int, 3> resolution() const override { return {data_.xres, data_.yres, data_.zres}; }
    std::string to_string() const override;

    // Value at a point of the unit cube (local coordinates), without the outside test.
    Rgb eval_local(const Vec3& u) const;
    const VolumeGridData& data() const { return data_; }

    // When false, max_in() bounds only the voxels whose centres lie in the query box and
    // forgets the neighbours that trilinear interpolation also reads. Wrong on purpose: lets the
    // tests check that they detect an unsafe majorant. Never set outside tests.
    bool include_interpolation_neighbours = true;

  private:
    Rgb voxel(int x, int y, int z) const;

    VolumeGridData data_;
    Transform to_world_, to_local_;
    VolumeFilter filter_;
    std::string name_;
    Aabb bounds_;
    float max_ = 0;
};

}  // namespace render
