// The eye pass of the bidirectional algorithms: each pixel's eye subpath, with every
// technique the plan turns on at each of its vertices.
#include "core/integrators/bidirectional/iteration.h"

namespace render::bidirectional {

Rgb Iteration::trace_eye_path(uint64_t pixel, RenderStats& stats, const LayerSink& sink) const {
    Rng rng(StreamKey{key_.seed, key_.frame, key_.iteration, pixel});
    SubpathState state;
    Ray ray = start_eye_path(pixel, rng, state);

    Rgb color(0.0f);
    // s light vertices and t = path_length + 1 eye vertices (the camera included).
    auto add = [&](Technique kind, int s, const Rgb& contribution) {
        color += contribution;
        sink.add(kind, s, state.path_length + 1, contribution);
    };
    // The pixel's light path (connections and joint connections).
    uint32_t light_first = 0, light_end = 0;
    uint32_t rays_first = 0, rays_end = 0;  // its J2 light rays
    if (plan_.vertex_connections && !plan_.ic_connections && !path_ends_.empty()) {
        const uint64_t path = pixel % plan_.light_path_count;
        light_first = path == 0 ? 0 : path_ends_[path - 1];
        light_end = path_ends_[path];
        if (path < ray_ends_.size()) {
            rays_first = path == 0 ? 0 : ray_ends_[path - 1];
            rays_end = ray_ends_[path];
        }
    }
    // The gathers' closest hits along the segment about to be sampled (next_vertex reuses them).
    TracedPieces traced;
    for (;; ++state.path_length) {
        if (plan_.joint && state.path_length < plan_.max_length)
            joint_connections(ray, state, light_first, light_end, rays_first, rays_end, rng, stats,
                              [&](int s, const Rgb& c) { add(Technique::Connection, s, c); });
        traced.count = 0;
        if (plan_.query_beams && plan_.photon_beams && state.path_length < plan_.max_length) {
            Rgb query_sum, photon_sum;
            both_beams(ray, state, rng, stats, query_sum, photon_sum, &traced);
            add(Technique::Merging, 0, state.throughput * query_sum);
            add(Technique::Merging, 0, state.throughput * photon_sum);
        } else if (plan_.query_beams && state.path_length < plan_.max_length) {
            add(Technique::Merging, 0,
                state.throughput * query_beams(ray, state, rng, stats, &traced));
        } else if (plan_.photon_beams && state.path_length < plan_.max_length) {
            add(Technique::Merging, 0,
                state.throughput * photon_beams(ray, state, rng, stats, &traced));
        }
        SampledSegment seg;
        std::optional<SubpathVertex> v =
            next_vertex(ray, TransportMode::Radiance, rng, state, stats, seg, &traced);
        if (!v) {
            if (seg.end == SegmentEnd::Escaped && !state.throughput.is_black())
                escaped_emission(state, ray, seg,
                                 [&](const Rgb& c) { add(Technique::Connection, 0, c); });
            break;
        }
        const Vec3 wo = -ray.direction;
        if (!v->in_medium() && seg.si.emitter)
            add(Technique::Connection, 0,
                state.throughput * emission(seg.si.emitter, state,
                                            seg.si.emitter->radiance_at(seg.si, ray.direction),
                                            v->p, seg.medium));
        if (v->in_medium() && v->medium->is_emissive() && !scene_.volume_lights().empty()) {
            add(Technique::Connection, 0, medium_emission(state, *v));
            if (state.throughput.is_black()) break;  // nothing scatters here (albedo 0)
        }
        if (state.path_length >= plan_.max_length) break;
        // Every technique below treats v as a scattering vertex (emission above: as the light).
        include_joint_junction(state.mis, state, *v);

        // Light tracing and PPM leave every non-delta scattering of the eye path to the light
        // paths (camera connections or the one merge); the eye continues only through delta
        // lobes, including the delta lobes of mixed materials such as plastic's coating.
        const bool eye_ends_at_non_delta = plan_.light_tracing_only || plan_.ppm;
        if (v->has_non_delta() && !plan_.light_tracing_only) {
            if (plan_.vertex_connections) {
                add(Technique::Connection, 1,
                    state.throughput * direct_illumination(state, *v, wo, rng, stats));
            }
            if (plan_.ic_connections) {
                // (1 / N) sum over the N cached light paths of their connections to v: its
                // expectation is one light path's, so every MIS weight stays as it is.
                draw_from_importance_caches(
                    *v, state.path_length, rng,
                    [&](const LightVertex& lv) {
                        // No J2 beside ic connections (plan_.joint is off there).
                        return lv.throughput *
                               connect_vertices(lv, Joint2Vertex{}, *v, wo, state.mis, rng, stats) *
                               plan_.ic_connection_scale;
                    },
                    [&](int s, const Rgb& c) {
                        add(Technique::Connection, s, state.throughput * c);
                    });
            } else if (plan_.vertex_connections) {
                for (uint32_t i = light_first; i < light_end; ++i) {
                    const LightVertex& lv = light_vertices_[i];
                    if (lv.path_length + 1 + state.path_length > plan_.max_length) break;
                    add(Technique::Connection, lv.path_length + 1,
                        state.throughput * lv.throughput *
                            connect_vertices(lv, joint2_of(i), *v, wo, state.mis, rng, stats,
                                             media_of(i)));
                }
            }
            if (v->in_medium() ? plan_.merge_points : plan_.merge_surfaces) {
                add(Technique::Merging, 0, state.throughput * merge(*v, wo, state));
            }
        }
        if (eye_ends_at_non_delta && !v->has_delta()) break;
        if (!sample_scattering(*v, wo, rng, state, ray)) break;
        if (eye_ends_at_non_delta && !state.specular_path) break;
    }
    return color;
}

}  // namespace render::bidirectional
