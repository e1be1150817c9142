#include "core/integrators/bidirectional/bidirectional_integrator.h"

#include "core/integrators/bidirectional/iteration.h"

namespace render {

using bidirectional::Iteration;
using bidirectional::IterationStorage;
using bidirectional::KeptStorage;

BidirectionalIntegrator::BidirectionalIntegrator(const BidirectionalConfig& config)
    : config_(config), kept_(std::make_unique<KeptStorage>()) {}

BidirectionalIntegrator::~BidirectionalIntegrator() = default;

void BidirectionalIntegrator::render_iteration(const Scene& scene, const IterationKey& key,
                                               AccumulationBuffer& target, TechniqueLayers* layers,
                                               RenderStats& stats) const {
    bidirectional::run_iteration(
        bidirectional::plan_iteration(config_, scene, key.iteration), scene, key, *kept_, target,
        layers, stats, active_pixels(),
        [](Iteration& iteration, RenderStats& s) {
            if (iteration.plan().uses_importance_caches()) iteration.build_importance_cache(s);
        },
        [](const Iteration& iteration, uint64_t pixel, RenderStats& local, const LayerSink& sink) {
            return iteration.trace_eye_path(pixel, local, sink);
        });
}

PhotonBeamInspection BidirectionalIntegrator::inspect_photon_beams(const Scene& scene,
                                                                   const IterationKey& key) const {
    PhotonBeamInspection out;
    if (config_.algorithm != BidirectionalAlgorithm::Upbp || !config_.upbp.photon_beams ||
        (scene.lights().empty() && scene.volume_lights().empty()))
        return out;
    IterationStorage storage;
    Iteration iteration(bidirectional::plan_iteration(config_, scene, key.iteration), scene, key,
                        storage);
    RenderStats stats;
    iteration.trace_light_paths(stats, [](std::span<const bidirectional::Splat>) {});
    out.lines = storage.photon_beam_lines;
    out.radius = iteration.plan().photon_beam_radius;
    return out;
}

}  // namespace render
