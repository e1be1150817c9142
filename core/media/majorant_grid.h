#pragma once

// A majorant grid: a coarse grid over a density volume's bounds holding, per cell, an upper
// bound of the density *as the volume interpolates it* anywhere in the cell (Volume::max_in,
// which includes the neighbouring voxels that trilinear interpolation reads), times a scale.
// Delta and ratio tracking sample tentative collisions with these piecewise-constant
// majorants, cell by cell, along a ray (a 3-D DDA, Amanatides and Woo 1987).
//
// A volume with unbounded support (a constant) gets one infinite cell.

#include <array>
#include <vector>

#include "core/math/ray.h"
#include "core/media/volume.h"

namespace render {

// The interval (t0, t1) of a ray inside one cell, and that cell's majorant.
struct MajorantSegment {
    float t0 = 0, t1 = 0;
    float majorant = 0;
};

class MajorantGrid {
  public:
    // `resolution` cells per axis over density.bounds(); {0, 0, 0} chooses
    // default_resolution(density.resolution()).
    MajorantGrid(const Volume& density, float scale, std::array<int, 3> resolution = {0, 0, 0});

    // One cell per 8 voxels (rounded up), between 1 and 64 cells per axis.
    static std::array<int, 3> default_resolution(std::array<int, 3> voxels);

    const Aabb& bounds() const { return bounds_; }
    bool bounded() const { return bounded_; }
    std::array<int, 3> resolution() const { return res_; }
    float at(int x, int y, int z) const {
        return values_[(size_t(z) * size_t(res_[1]) + size_t(y)) * size_t(res_[0]) + size_t(x)];
    }
    Aabb cell_bounds(int x, int y, int z) const;
    float max_majorant() const { return max_; }

    // Clips (t_min, t_max) of `ray` to the grid's bounds; false when nothing is left.
    bool clip(const Ray& ray, float t_min, float t_max, float& t0, float& t1) const;

    // Walks the cells a ray segment crosses, in order, as consecutive segments.
    class Iterator {
      public:
        // Next segment; false when the ray has left the grid or reached the segment's end.
        bool next(MajorantSegment& out);

      private:
        friend class MajorantGrid;
        const MajorantGrid* grid_ = nullptr;
        Vec3 origin_, direction_;
        float t_ = 0, t_end_ = 0;
        int cell_[3] = {0, 0, 0};
        int step_[3] = {0, 0, 0};
        bool done_ = true;
        float next_crossing(int axis) const;
    };
    Iterator traverse(const Ray& ray, float t_min, float t_max) const;

  private:
    Aabb bounds_;
    bool bounded_ = false;
    std::array<int, 3> res_{1, 1, 1};
    Vec3 cell_size_;
    std::vector<float> values_;
    float max_ = 0;
};

}  // namespace render
