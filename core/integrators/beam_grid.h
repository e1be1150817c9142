#pragma once

// The alternative lookup for upbp's photon beams, measured against BeamsAlongRay (Embree user
// geometry) in bench/beam_lookup.cpp (docs/design/media.md, "Photon beams in grid media": the
// figures). A uniform grid over the beams' bounds (clipped to a given box); each beam is
// registered in every cell its capsule of radius r overlaps (walked in steps of one cell, each
// step's box grown by r), and a query walks the cells its segment crosses (3-D DDA), testing
// each registered beam's closest approach and accepting it only in the cell whose stretch of
// the query holds that approach, so no beam is reported twice. SmallUPBP's lookup is a grid of
// this kind. Same contract as BeamsAlongRay::for_each_near.

#include <cstdint>
#include <type_traits>
#include <vector>

#include "core/base/shape.h"
#include "core/integrators/beams_along_ray.h"

namespace render {

class UniformBeamGrid {
  public:
    // `bounds`: where queries can be (the scene's box); beams are clipped to it grown by r.
    // `cells_per_beam`: the grid has about this many cells per beam (at most 256 per axis).
    void build(const std::vector<BeamLine>& beams, float radius, const Aabb& bounds,
               double cells_per_beam = 1.0);

    template <typename Visit>
    void for_each_near(const Ray& ray, Visit&& visit) const {
        query(
            ray,
            [](void* user, uint32_t i, const BeamApproach& a) {
                (*static_cast<std::remove_reference_t<Visit>*>(user))(i, a);
            },
            &visit);
    }
    void query(const Ray& ray, BeamsAlongRay::VisitFunction visit, void* user) const;

    // The grid's box (empty when it holds no beam): no query outside it finds a beam.
    Aabb bounds() const { return beam_ids_.empty() ? Aabb{} : Aabb{lo_, hi_}; }
    size_t references() const { return beam_ids_.size(); }
    int resolution(int axis) const { return res_[axis]; }

  private:
    const std::vector<BeamLine>* beams_ = nullptr;
    float radius_ = 0;
    Vec3 lo_, hi_, cell_size_;
    int res_[3] = {0, 0, 0};
    std::vector<uint32_t> cell_start_;  // CSR: cell c holds beam_ids_[cell_start_[c] ..)
    std::vector<uint32_t> beam_ids_;
};

}  // namespace render
