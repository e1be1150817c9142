#pragma once

// Many-light rendering (instant radiosity) over the light paths of the bidirectional family's
// light pass: `vpl` connects each shading point to every virtual point light, optionally from the
// importance-driven VPL distribution (Georgiev and Slusallek 2010); `ic` draws a few VPLs from
// importance caches (Georgiev, Krivanek, Popov and Slusallek 2012). Every estimate has weight 1:
// none of the VCM MIS takes part. docs/reference/algorithms.md, "Many-light rendering".

#include <memory>
#include <mutex>

#include "core/integrators/bidirectional/config.h"
#include "core/integrators/bidirectional/iteration.h"
#include "core/integrators/integrator.h"

namespace render {

class ManyLightIntegrator final : public Integrator {
  public:
    explicit ManyLightIntegrator(const ManyLightConfig& config);
    ~ManyLightIntegrator() override;

    void render_iteration(const Scene& scene, const IterationKey& key, AccumulationBuffer& target,
                          TechniqueLayers* layers, RenderStats& stats) const override;
    // Eye paths from the active pixels only; the VPLs, records and caches are built whole
    // (docs/reference/adaptive-sampling.md, "The bidirectional family").
    bool takes_active_pixels() const override { return true; }

    const ManyLightConfig& config() const { return config_; }

    // The importance-driven distribution's view of one iteration (vpl with the importance
    // distribution): every candidate with its estimate and draw. It repeats the iteration's
    // light and record passes, so its numbers are those render_iteration uses; for tests and
    // diagnostics.
    VplSelection inspect_vpl_selection(const Scene& scene, const IterationKey& key) const;

  private:
    ManyLightConfig config_;
    mutable std::unique_ptr<bidirectional::KeptStorage> kept_;  // iteration_storage.h
};

}  // namespace render
