#include "core/media/grid_volume.h"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "core/base/error.h"

namespace render {
namespace {

int clamp_index(float x, int res) {
    // Compare as float first: a huge x must not overflow the int conversion.
    if (!(x > 0)) return 0;
    if (x >= float(res - 1)) return res - 1;
    return int(x);
}

}  // namespace

GridVolume::GridVolume(VolumeGridData data, const Transform& to_world, VolumeFilter filter,
                       std::string name)
    : data_(std::move(data)),
      to_world_(to_world),
      to_local_(to_world.inverse()),
      filter_(filter),
      name_(std::move(name)) {
    if (data_.xres < 1 || data_.yres < 1 || data_.zres < 1 ||
        (data_.channels != 1 && data_.channels != 3) ||
        data_.values.size() != data_.voxel_count() * size_t(data_.channels))
        throw SceneError(name_ + ": inconsistent volume grid");
    if (to_world.is_singular()) throw SceneError(name_ + ": to_world is singular");
    for (int c = 0; c < 8; ++c)
        bounds_.expand(to_world_.apply_point(
            Vec3((c & 1) ? 1.0f : 0.0f, (c & 2) ? 1.0f : 0.0f, (c & 4) ? 1.0f : 0.0f)));
    max_ = 0;
    for (float v : data_.values) max_ = std::max(max_, v);
}

Rgb GridVolume::voxel(int x, int y, int z) const {
    const size_t i =
        ((size_t(z) * size_t(data_.yres) + size_t(y)) * size_t(data_.xres) + size_t(x)) *
        size_t(data_.channels);
    if (data_.channels == 1) return Rgb(data_.values[i]);
    return Rgb(data_.values[i], data_.values[i + 1], data_.values[i + 2]);
}

Rgb GridVolume::eval_local(const Vec3& u) const {
    const int res[3] = {data_.xres, data_.yres, data_.zres};
    if (filter_ == VolumeFilter::kNearest) {
        int i[3];
        for (int a = 0; a < 3; ++a) i[a] = clamp_index(std::floor(u[a] * float(res[a])), res[a]);
        return voxel(i[0], i[1], i[2]);
    }
    int i0[3], i1[3];
    float w[3];
    for (int a = 0; a < 3; ++a) {
        const float x = u[a] * float(res[a]) - 0.5f;
        const float f = std::floor(x);
        w[a] = x - f;
        i0[a] = clamp_index(f, res[a]);
        i1[a] = clamp_index(f + 1.0f, res[a]);
    }
    auto lerp = [](const Rgb& a, const Rgb& b, float t) { return a * (1.0f - t) + b * t; };
    const Rgb c00 = lerp(voxel(i0[0], i0[1], i0[2]), voxel(i1[0], i0[1], i0[2]), w[0]);
    const Rgb c10 = lerp(voxel(i0[0], i1[1], i0[2]), voxel(i1[0], i1[1], i0[2]), w[0]);
    const Rgb c01 = lerp(voxel(i0[0], i0[1], i1[2]), voxel(i1[0], i0[1], i1[2]), w[0]);
    const Rgb c11 = lerp(voxel(i0[0], i1[1], i1[2]), voxel(i1[0], i1[1], i1[2]), w[0]);
    return lerp(lerp(c00, c10, w[1]), lerp(c01, c11, w[1]), w[2]);
}

Rgb GridVolume::eval(const Vec3& p) const {
    const Vec3 u = to_local_.apply_point(p);
    if (!(u.x >= 0 && u.x <= 1 && u.y >= 0 && u.y <= 1 && u.z >= 0 && u.z <= 1)) return Rgb(0.0f);
    return eval_local(u);
}

float GridVolume::max_in(const Aabb& world_box) const {
    if (world_box.empty()) return 0;
    if (!is_bounded(world_box)) return max_;
    // The local box of the world box's corners (to_local is affine, so this contains the image
    // of the whole box), widened a little against rounding in the transform.
    Aabb local;
    for (int c = 0; c < 8; ++c)
        local.expand(to_local_.apply_point(Vec3((c & 1) ? world_box.hi.x : world_box.lo.x,
                                                (c & 2) ? world_box.hi.y : world_box.lo.y,
                                                (c & 4) ? world_box.hi.z : world_box.lo.z)));
    constexpr float kMargin = 1e-5f;
    const int res[3] = {data_.xres, data_.yres, data_.zres};
    int lo[3], hi[3];
    for (int a = 0; a < 3; ++a) {
        const float l = std::max(local.lo[a] - kMargin, 0.0f);
        const float h = std::min(local.hi[a] + kMargin, 1.0f);
        if (l > h) return 0;  // the box misses the unit cube: the value there is 0
        const float r = float(res[a]);
        if (filter_ == VolumeFilter::kTrilinear && include_interpolation_neighbours) {
            // A lookup at u reads voxels floor(u r - 1/2) and floor(u r - 1/2) + 1.
            lo[a] = clamp_index(std::floor(l * r - 0.5f), res[a]);
            hi[a] = clamp_index(std::floor(h * r - 0.5f) + 1.0f, res[a]);
        } else if (filter_ == VolumeFilter::kNearest) {
            // Nearest: the voxels whose own box [i, i+1] / r meets [l, h].
            lo[a] = clamp_index(std::floor(l * r), res[a]);
            hi[a] = clamp_index(std::floor(h * r), res[a]);
        } else {
            // The test hook's wrong bound: only the voxels whose centres lie in [l, h].
            lo[a] = clamp_index(std::ceil(l * r - 0.5f), res[a]);
            hi[a] = clamp_index(std::floor(h * r - 0.5f), res[a]);
            if (lo[a] > hi[a]) return 0;
        }
    }
    float m = 0;
    for (int z = lo[2]; z <= hi[2]; ++z)
        for (int y = lo[1]; y <= hi[1]; ++y)
            for (int x = lo[0]; x <= hi[0]; ++x) m = std::max(m, voxel(x, y, z).max());
    // Interpolation's rounding may exceed the largest voxel by a few ulps.
    return m * (1.0f + 0x1p-16f);
}

std::string GridVolume::to_string() const {
    std::ostringstream os;
    os << "gridvolume(" << (name_.empty() ? std::string("<memory>") : name_) << ", " << data_.xres
       << "x" << data_.yres << "x" << data_.zres << ", " << data_.channels
       << (data_.channels == 1 ? " channel" : " channels")
       << ", filter=" << (filter_ == VolumeFilter::kNearest ? "nearest" : "trilinear")
       << ", max=" << max_ << ")";
    return os.str();
}

}  // namespace render
