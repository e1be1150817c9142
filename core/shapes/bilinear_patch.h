#pragma once

// Bilinear patches (pbrt-v4's `bilinearmesh` when a patch is not planar): patch i has corners
// (p00, p10, p01, p11) and the surface
//   p(u, v) = (1 - v) ((1 - u) p00 + u p10) + v ((1 - u) p01 + u p11),   (u, v) in [0, 1]^2.
// Embree user geometry, one primitive per patch; the ray test intersects the ray with the
// family of straight lines u = const that make up the patch (a quadratic in u, then v and t
// from the closest points of two lines), in double precision.
//
// Conventions, as pbrt-v4 and our TriangleMesh:
//   geometric normal  cross(dp/du, dp/dv), flipped by `flip_normals` (the loader passes
//                     ReverseOrientation xor a mirroring transform); with vertex normals, turned
//                     to their side (and the shading normal is their bilinear interpolation);
//   uv                the bilinear interpolation of the vertex uvs, or (u, 1 - v) without them
//                     (v flipped to our lookups' convention, as the loaders flip mesh uvs).
//
// Area sampling (for area lights), as pbrt-v4: a patch by its area, then (u, v) by the bilinear
// density through the area element |dp/du x dp/dv| at the four corners, so
//   pdf_area(p) = P(patch) * bilinear_pdf(u, v) / |dp/du x dp/dv|(u, v),
// which is not uniform. pdf_area() gives the same density for a hit's patch and (u, v), and
// locate() finds them for a point alone. docs/reference/scene-format.md, "Bilinear patches".

#include <array>
#include <optional>
#include <string>
#include <vector>

#include "core/base/shape.h"
#include "core/sampling/distribution.h"

namespace render {

// The bilinear warp: (x, y) in [0, 1)^2 with density proportional to the bilinear
// interpolation of the corner weights w = {w00, w10, w01, w11} (non-negative, not all zero;
// all zero gives the identity).
Vec2 sample_bilinear(Vec2 u, const std::array<float, 4>& w);
float bilinear_pdf(Vec2 p, const std::array<float, 4>& w);

class BilinearPatches final : public Shape {
  public:
    // World-space positions; `indices` holds 4 per patch (p00, p10, p01, p11). `normals` (unit,
    // world space, used as given: `flip_normals` does not turn them) and `uvs` (our convention)
    // are empty or one per position. Throws SceneError
    // (naming `name`) for a bad index count or index, a non-finite position, or no patches.
    BilinearPatches(std::vector<Vec3> positions, std::vector<uint32_t> indices,
                    std::vector<Vec3> normals, std::vector<Vec2> uvs, bool flip_normals,
                    std::string name);

    unsigned attach(RTCDevice device, RTCScene scene) const override;
    void fill_interaction(const Ray& ray, float t, unsigned prim_id, float u, float v,
                          HitDetail detail, SurfaceInteraction& si) const override;
    Aabb bounds() const override;
    // Sum of the patches' areas (Gauss-Legendre quadrature of the area element).
    float surface_area() const override { return area_; }
    // Not uniform: see the header comment; pdf_area is the density at the sampled point.
    ShapeSample sample_area(Vec2 u) const override;
    // The density sample_area() has at patch `prim_id`'s point (u, v) = prim_uv (0 off it).
    float pdf_area(unsigned prim_id, Vec2 prim_uv) const override;
    // The patch and its (u, v) whose point is p (nearest within a small tolerance): a search
    // over every patch, for callers that have only the point.
    bool locate(const Vec3& p, unsigned& prim_id, Vec2& prim_uv) const override;
    std::string to_string() const override;

    bool has_uv_lookup() const override { return true; }
    Vec2 uv_at(const Vec3& p) const override;
    Vec2 uv_at_hit(unsigned prim_id, Vec2 prim_uv, const Vec3&) const override {
        return uv_of(prim_id, prim_uv.x, prim_uv.y);
    }

    struct PatchHit {
        double t, u, v;
    };
    // Nearest hit of the ray with patch i in (t_min, t_max) that the cut-out keeps.
    std::optional<PatchHit> intersect_patch(size_t i, const double org[3], const double dir[3],
                                            double t_min, double t_max) const;
    size_t patch_count() const { return indices_.size() / 4; }
    Vec3 point(size_t i, double u, double v) const;
    // |dp/du x dp/dv| of patch i at (u, v).
    double area_element(size_t i, double u, double v) const;
    double patch_area(size_t i) const { return patch_areas_[i]; }

  private:
    const Vec3& corner(size_t i, int k) const { return positions_[indices_[4 * i + k]]; }
    Vec2 uv_of(size_t i, double u, double v) const;
    Aabb patch_bounds(size_t i) const;

    std::vector<Vec3> positions_;
    std::vector<uint32_t> indices_;
    std::vector<Vec3> normals_;
    std::vector<Vec2> uvs_;
    std::vector<double> patch_areas_;
    std::vector<std::array<float, 4>> corner_weights_;  // the area element at the corners
    Distribution1D patch_distribution_;                 // by area
    float area_ = 0;
    bool flip_normals_;
    std::string name_;
};

}  // namespace render
