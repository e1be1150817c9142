#pragma once

// Importance sampling of a textured area light on a triangle mesh, by radiance x area.
//
// Each triangle is cut into K x K (K^2) equal sub-triangles (a uniform grid in its barycentric
// coordinates: K(K+1)/2 upright and K(K-1)/2 upside-down cells), K from 16 down to 1 so that the
// whole mesh has at most kMaxCells cells. A cell's weight is its area times
// (its luminance at the centroid + 1/10 of the mesh's area-weighted mean luminance): the
// defensive part keeps the density positive wherever the texture could emit, so a feature
// smaller than a cell is sampled, only less well. A point is sampled by picking a cell by
// weight and a point uniformly in it: pdf_area = P(cell) / area(cell).
//
// The same density is found back from a point (an emitter hit): a uniform grid over the mesh's
// bounds lists the triangles whose (slightly enlarged) bounds overlap each grid cell; the
// triangle nearest to the point among those whose barycentrics contain it gives the uv and the
// cell. This also gives textured radiance to meshes of any size (TriangleMesh's own uv_at
// searches every triangle).

#include <cstdint>
#include <vector>

#include "core/base/interaction.h"
#include "core/base/shape.h"
#include "core/sampling/distribution.h"
#include "core/textures/texture.h"

namespace render {

class TriangleMesh;

class TexturedMeshEmission {
  public:
    static constexpr size_t kMaxCells = size_t(1) << 17;

    // `mesh` must outlive this.
    TexturedMeshEmission(const TriangleMesh& mesh, const Texture& radiance);

    // A point by radiance x area: p, its face normal, uv and pdf_area (0: nothing to sample).
    ShapeSample sample(Vec2 u) const;

    // The uv and pdf_area sample() gives the point p of the mesh (false when p is on none of
    // its triangles); `cell`, when given, gets the point's cell: triangle t's cells are
    // 2 K^2 t + 2 (i K + j) + d for the barycentric grid cell (i, j), upside down when d = 1.
    bool find(const Vec3& p, Vec2& uv, float& pdf_area, size_t* cell = nullptr) const;
    // The triangle of the mesh and barycentrics (b1, b2) of point p, as find() picks them.
    bool locate(const Vec3& p, unsigned& tri, Vec2& barycentrics) const;
    // The pdf_area sample() gives the point of triangle `tri` at barycentrics (b1, b2): an
    // emitter hit's density without a point lookup.
    float pdf_at(unsigned tri, Vec2 barycentrics) const {
        return pdf_of(tri, cell_of(barycentrics.x, barycentrics.y));
    }

    int subdivision() const { return k_; }  // K
    // Entries of the locator's lists (at most 16 a triangle, + 4096).
    size_t locator_entries() const { return grid_triangles_.size(); }

  private:
    // The cell of barycentrics (b1, b2) in a triangle: index within the triangle's 2 K^2 slots
    // (slot (i, j, upside-down) = 2 (i K + j) + d; unused slots have weight 0).
    size_t cell_of(float b1, float b2) const;
    float pdf_of(size_t tri, size_t cell) const;
    // Barycentrics of p in triangle `tri`, and the distance of p from its plane; false when
    // p's projection is outside it (with a margin for rounding) or it is degenerate.
    bool barycentrics(size_t tri, const Vec3& p, float& b1, float& b2, float& distance) const;

    const TriangleMesh& mesh_;
    int k_ = 1;
    Distribution1D cells_;          // triangle t's slots at [2 K^2 t, 2 K^2 (t + 1))
    std::vector<float> cell_area_;  // per triangle: its area / K^2

    // The point locator: a grid of n_[0] x n_[1] x n_[2] cells over [lo_, lo_ + n_ size_).
    Vec3 lo_, cell_size_;
    int n_[3] = {1, 1, 1};
    std::vector<uint32_t> grid_start_;  // CSR: triangles of grid cell c at [start[c], start[c+1])
    std::vector<uint32_t> grid_triangles_;
};

}  // namespace render
