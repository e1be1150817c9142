#pragma once

#include "core/integrators/integrator.h"
#include "core/integrators/volpt_technique.h"

namespace render {

// Volumetric path tracing (`volpt`): the path tracer extended to participating media.
// - Free-flight distances come from the medium's own sampling (analytic or delta tracking);
//   index-matched (null) boundaries are crossed without counting a bounce.
// - Next-event estimation at surface and medium vertices, with transmittance along the shadow
//   ray (through null boundaries and every medium on the way).
// - Equi-angular sampling (Kulla and Fajardo 2012) of single scattering toward a point on a
//   finite light, on every medium segment, combined with the two distance-sampled techniques
//   (light sampling and phase sampling at a distance-sampled vertex) by the power heuristic
//   over all three. All three densities are expressed per unit length times solid angle at
//   the medium vertex, so one path's three densities are directly comparable.
// - Joint path sampling (Georgiev et al. 2013, technique J3) of double scattering on the
//   camera ray's medium pieces in homogeneous media: c on the camera ray, b on a ray from c and
//   the light point are sampled together so that the geometry terms cancel; combined with the
//   three techniques above by the power heuristic over four (the weights of every path
//   camera -> c -> b -> light include J3's density). docs/design/media.md, "Joint path sampling".
// `technique` replaces this MIS by single unweighted techniques, for measuring convergence rates
// (volpt_technique.h).
// max_depth counts segments as Mitsuba does (medium vertices count, null crossings do not).
// Russian roulette acts on throughput below 1 only (see survives_roulette).
class VolumetricPathTracer final : public PixelIntegrator {
  public:
    VolumetricPathTracer(int max_depth, int rr_depth, bool equiangular, bool jis,
                         VolptTechnique technique = VolptTechnique::All)
        : max_depth_(max_depth),
          rr_depth_(rr_depth),
          equiangular_(equiangular && technique != VolptTechnique::DistanceLight),
          jis_((jis || technique == VolptTechnique::Joint) &&
               technique != VolptTechnique::DistanceLight),
          technique_(technique) {}

  protected:
    Rgb Li(const Scene& scene, const Ray& ray, Rng& rng, RenderStats& stats,
           const LayerSink& sink) const override;

  private:
    // Segments after which a path ends whatever its throughput.
    static constexpr int kMaxSegments = 100000;
    bool survives_roulette(int depth, Rgb& beta, Rng& rng) const;

    int max_depth_;
    int rr_depth_;
    bool equiangular_;
    bool jis_;
    VolptTechnique technique_;
};

}  // namespace render
