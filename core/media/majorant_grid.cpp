#include "core/media/majorant_grid.h"

#include <algorithm>
#include <cmath>

namespace render {

std::array<int, 3> MajorantGrid::default_resolution(std::array<int, 3> voxels) {
    std::array<int, 3> r;
    for (int a = 0; a < 3; ++a) r[a] = std::clamp((std::max(voxels[a], 1) + 7) / 8, 1, 64);
    return r;
}

MajorantGrid::MajorantGrid(const Volume& density, float scale, std::array<int, 3> resolution) {
    bounds_ = density.bounds();
    bounded_ = is_bounded(bounds_);
    if (!bounded_) {
        res_ = {1, 1, 1};
        values_ = {scale * density.max_value()};
        max_ = values_[0];
        return;
    }
    if (resolution[0] < 1 || resolution[1] < 1 || resolution[2] < 1)
        resolution = default_resolution(density.resolution());
    res_ = resolution;
    const Vec3 extent = bounds_.hi - bounds_.lo;
    cell_size_ =
        Vec3(extent.x / float(res_[0]), extent.y / float(res_[1]), extent.z / float(res_[2]));
    values_.resize(size_t(res_[0]) * size_t(res_[1]) * size_t(res_[2]));
    size_t i = 0;
    for (int z = 0; z < res_[2]; ++z)
        for (int y = 0; y < res_[1]; ++y)
            for (int x = 0; x < res_[0]; ++x) {
                // The cell widened by 0.1 % of its size: the points at which tracking evaluates
                // the density lie in the DDA's cell up to rounding of o + t d.
                Aabb box = cell_bounds(x, y, z);
                const Vec3 margin = cell_size_ * 1e-3f;
                box.lo -= margin;
                box.hi += margin;
                values_[i] = scale * density.max_in(box);
                max_ = std::max(max_, values_[i]);
                ++i;
            }
}

Aabb MajorantGrid::cell_bounds(int x, int y, int z) const {
    if (!bounded_) return bounds_;
    Aabb b;
    const int c[3] = {x, y, z};
    for (int a = 0; a < 3; ++a) {
        b.lo[a] = bounds_.lo[a] + float(c[a]) * cell_size_[a];
        // The last cell ends exactly on the bounds.
        b.hi[a] =
            c[a] + 1 == res_[a] ? bounds_.hi[a] : bounds_.lo[a] + float(c[a] + 1) * cell_size_[a];
    }
    return b;
}

bool MajorantGrid::clip(const Ray& ray, float t_min, float t_max, float& t0, float& t1) const {
    t0 = t_min;
    t1 = t_max;
    if (!bounded_) return t0 < t1;
    for (int a = 0; a < 3; ++a) {
        const float o = ray.origin[a], d = ray.direction[a];
        if (d == 0) {
            if (o < bounds_.lo[a] || o > bounds_.hi[a]) return false;
            continue;
        }
        const float inv = 1.0f / d;
        float near = (bounds_.lo[a] - o) * inv, far = (bounds_.hi[a] - o) * inv;
        if (near > far) std::swap(near, far);
        t0 = std::max(t0, near);
        t1 = std::min(t1, far);
    }
    return t0 < t1;
}

MajorantGrid::Iterator MajorantGrid::traverse(const Ray& ray, float t_min, float t_max) const {
    Iterator it;
    it.grid_ = this;
    it.origin_ = ray.origin;
    it.direction_ = ray.direction;
    float t0, t1;
    if (!clip(ray, t_min, t_max, t0, t1)) return it;  // done
    it.t_ = t0;
    it.t_end_ = t1;
    it.done_ = false;
    if (!bounded_) return it;
    const Vec3 p = ray.at(t0);
    for (int a = 0; a < 3; ++a) {
        const float x = (p[a] - bounds_.lo[a]) / cell_size_[a];
        it.cell_[a] =
            std::clamp(int(std::clamp(std::floor(x), 0.0f, float(res_[a] - 1))), 0, res_[a] - 1);
        it.step_[a] = ray.direction[a] > 0 ? 1 : (ray.direction[a] < 0 ? -1 : 0);
    }
    return it;
}

float MajorantGrid::Iterator::next_crossing(int a) const {
    if (step_[a] == 0) return kInfinity;
    const MajorantGrid& g = *grid_;
    // The plane the ray leaves the current cell through, recomputed from the cell index (no
    // accumulated error).
    const int plane = step_[a] > 0 ? cell_[a] + 1 : cell_[a];
    const float x =
        plane == g.res_[a] ? g.bounds_.hi[a] : g.bounds_.lo[a] + float(plane) * g.cell_size_[a];
    return (x - origin_[a]) / direction_[a];
}

bool MajorantGrid::Iterator::next(MajorantSegment& out) {
    if (done_) return false;
    const MajorantGrid& g = *grid_;
    out.t0 = t_;
    if (!g.bounded_) {
        out.t1 = t_end_;
        out.majorant = g.values_[0];
        done_ = true;
        return true;
    }
    out.majorant = g.at(cell_[0], cell_[1], cell_[2]);
    int axis = 0;
    float t_next = next_crossing(0);
    for (int a = 1; a < 3; ++a) {
        const float t = next_crossing(a);
        if (t < t_next) t_next = t, axis = a;
    }
    if (!(t_next < t_end_)) {
        out.t1 = t_end_;
        done_ = true;
        return true;
    }
    out.t1 = std::max(t_next, t_);
    t_ = out.t1;
    cell_[axis] += step_[axis];
    if (cell_[axis] < 0 || cell_[axis] >= g.res_[axis]) done_ = true;
    return true;
}

}  // namespace render
