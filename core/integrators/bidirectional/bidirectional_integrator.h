#pragma once

// The bidirectional family on one set of MIS quantities: light tracing, bidirectional path
// tracing, progressive photon mapping, bidirectional photon mapping, vertex connection and
// merging (Georgiev, Krivanek, Davidovic and Slusallek 2012) and unified points, beams and paths
// (Krivanek et al. 2014). The implementation follows the technical report "Implementing Vertex
// Connection and Merging" (Georgiev 2012, below "the report"): every subpath carries the
// recursive partial weights dVCM, dVC and dVM, from which every technique's MIS weight is
// computed locally. The algorithms differ only in which techniques they enable: the
// configuration (config.h) says which, the iteration's plan (iteration_plan.h) holds the result.

#include <memory>
#include <mutex>
#include <vector>

#include "core/integrators/beams_along_ray.h"
#include "core/integrators/bidirectional/config.h"
#include "core/integrators/integrator.h"

namespace render {

// One iteration's photon beams as the beam lookup sees them (upbp with photon beams), for the
// benchmark of the lookup (bench/beam_lookup.cpp).
struct PhotonBeamInspection {
    std::vector<BeamLine> lines;
    double radius = 0;
};

namespace bidirectional {
struct KeptStorage;  // iteration_storage.h
}  // namespace bidirectional

class BidirectionalIntegrator final : public Integrator {
  public:
    explicit BidirectionalIntegrator(const BidirectionalConfig& config);
    ~BidirectionalIntegrator() override;

    void render_iteration(const Scene& scene, const IterationKey& key, AccumulationBuffer& target,
                          TechniqueLayers* layers, RenderStats& stats) const override;
    // Eye subpaths from the active pixels only, the light pass whole: the light tracer's splats
    // into inactive pixels are dropped (docs/reference/adaptive-sampling.md, "The bidirectional
    // family").
    bool takes_active_pixels() const override { return true; }

    const BidirectionalConfig& config() const { return config_; }

    // The photon beams of one iteration (upbp with photon beams; empty otherwise), as the
    // iteration builds them; for benchmarks.
    PhotonBeamInspection inspect_photon_beams(const Scene& scene, const IterationKey& key) const;

  private:
    BidirectionalConfig config_;
    mutable std::unique_ptr<bidirectional::KeptStorage> kept_;  // iteration_storage.h
};

}  // namespace render
