#pragma once

#include "core/integrators/integrator.h"

namespace render {

// Debug shading: |cos| between the shading normal and the view ray, so geometry and normals
// can be checked without any light transport. Black where rays escape.
class EyeLight final : public PixelIntegrator {
  protected:
    Rgb Li(const Scene& scene, const Ray& ray, Rng& rng, RenderStats& stats,
           const LayerSink& sink) const override;
};

}  // namespace render
