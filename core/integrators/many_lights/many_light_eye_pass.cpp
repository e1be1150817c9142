#include "core/integrators/many_lights/many_light_eye_pass.h"

namespace render {

using bidirectional::LightVertex;
using bidirectional::SubpathState;
using bidirectional::SubpathVertex;

Rgb trace_many_light_eye_path(const bidirectional::Iteration& iteration, uint64_t pixel,
                              RenderStats& stats, const LayerSink& sink) {
    const bidirectional::IterationPlan& plan = iteration.plan();
    const IterationKey& key = iteration.key();
    Rng rng(StreamKey{key.seed, key.frame, key.iteration, pixel});
    SubpathState state;
    Ray ray = iteration.start_eye_path(pixel, rng, state);

    Rgb color(0.0f);
    // s light vertices and t = path_length + 1 eye vertices (the camera included).
    auto add = [&](int s, const Rgb& contribution) {
        color += contribution;
        sink.add(Technique::Connection, s, state.path_length + 1, contribution);
    };
    for (;; ++state.path_length) {
        SampledSegment seg;
        std::optional<SubpathVertex> v =
            iteration.next_vertex(ray, TransportMode::Radiance, rng, state, stats, seg);
        if (!v) {
            if (seg.end == SegmentEnd::Escaped && !state.throughput.is_black())
                iteration.escaped_emission(state, ray, seg, [&](const Rgb& c) { add(0, c); });
            break;
        }
        const Vec3 wo = -ray.direction;
        if (!v->in_medium() && seg.si.emitter)
            add(0, state.throughput *
                       iteration.emission(seg.si.emitter, state,
                                          seg.si.emitter->radiance_at(seg.si, ray.direction), v->p,
                                          seg.medium));
        if (state.path_length >= plan.max_length) break;
        if (v->has_non_delta()) {
            add(1, state.throughput * iteration.direct_illumination(state, *v, wo, rng, stats));
            if (plan.ic) {
                iteration.draw_from_importance_caches(
                    *v, state.path_length, rng,
                    [&](const LightVertex& lv) {
                        return lv.throughput *
                               iteration.vpl_connection(lv, *v, wo, plan.vpl_clamp2, rng, stats);
                    },
                    [&](int s, const Rgb& c) { add(s, state.throughput * c); });
            }
            if (plan.vpl) {
                for (const LightVertex& lv : iteration.light_vertices()) {
                    if (lv.path_length + 1 + state.path_length > plan.max_length) continue;
                    add(lv.path_length + 1,
                        state.throughput * lv.throughput *
                            iteration.vpl_connection(lv, *v, wo, plan.vpl_clamp2, rng, stats));
                }
            }
        }
        // The eye goes on only through delta lobes, including the delta lobes of mixed
        // materials such as plastic's coating.
        if (!v->has_delta()) break;
        if (!iteration.sample_scattering(*v, wo, rng, state, ray)) break;
        if (!state.specular_path) break;
    }
    return color;
}

}  // namespace render
