#include "core/integrators/many_lights/many_light_integrator.h"

#include "core/integrators/many_lights/many_light_eye_pass.h"

namespace render {

using bidirectional::Iteration;
using bidirectional::IterationStorage;
using bidirectional::KeptStorage;

ManyLightIntegrator::ManyLightIntegrator(const ManyLightConfig& config)
    : config_(config), kept_(std::make_unique<KeptStorage>()) {}

ManyLightIntegrator::~ManyLightIntegrator() = default;

void ManyLightIntegrator::render_iteration(const Scene& scene, const IterationKey& key,
                                           AccumulationBuffer& target, TechniqueLayers* layers,
                                           RenderStats& stats) const {
    // The light pass's vertices are the VPLs (no splats: nothing connects to the camera).
    bidirectional::run_iteration(
        bidirectional::plan_iteration(config_, scene, key.iteration), scene, key, *kept_, target,
        layers, stats, active_pixels(),
        [&](Iteration& iteration, RenderStats& s) {
            if (iteration.plan().vpl && config_.importance.enabled) iteration.select_vpls(s);
            if (iteration.plan().ic) iteration.build_importance_cache(s);
        },
        [](const Iteration& iteration, uint64_t pixel, RenderStats& local, const LayerSink& sink) {
            return trace_many_light_eye_path(iteration, pixel, local, sink);
        });
}

VplSelection ManyLightIntegrator::inspect_vpl_selection(const Scene& scene,
                                                        const IterationKey& key) const {
    VplSelection selection;
    if (config_.estimator != ManyLightEstimator::Vpl || !config_.importance.enabled ||
        scene.lights().empty())
        return selection;
    IterationStorage storage;
    Iteration iteration(bidirectional::plan_iteration(config_, scene, key.iteration), scene, key,
                        storage);
    RenderStats stats;
    iteration.trace_light_paths(stats, [](std::span<const bidirectional::Splat>) {});
    iteration.select_vpls(stats, &selection);
    selection.light_paths = iteration.plan().light_path_count;
    selection.importance_records = config_.importance.records;
    selection.record_distance_clamp = std::sqrt(double(iteration.record_clamp2()));
    return selection;
}

}  // namespace render
