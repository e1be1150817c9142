#pragma once

#include "core/integrators/integrator.h"
#include "core/integrators/roulette.h"

namespace render {

// Unidirectional path tracing with next-event estimation. Emission found by BSDF sampling and
// by light sampling are combined with the power heuristic; delta BSDF lobes and delta lights
// take the only technique that can find them. max_depth counts path segments as Mitsuba does
// (1 = directly visible emitters only). Russian roulette by `roulette` (roulette.h): from
// rr_depth on by throughput, or at every bounce by the sampled weight.
class PathTracer final : public PixelIntegrator {
  public:
    PathTracer(int max_depth, int rr_depth, RoulettePolicy roulette = RoulettePolicy::Throughput)
        : max_depth_(max_depth), rr_depth_(rr_depth), roulette_(roulette) {}

  protected:
    Rgb Li(const Scene& scene, const Ray& ray, Rng& rng, RenderStats& stats,
           const LayerSink& sink) const override;

  private:
    int max_depth_;
    int rr_depth_;
    RoulettePolicy roulette_;
};

}  // namespace render
