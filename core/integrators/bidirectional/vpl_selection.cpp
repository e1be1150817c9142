// Many-light parts of the iteration: VPL connections, the importance records and the
// importance-driven VPL selection (Georgiev and Slusallek 2010).
#include "core/integrators/bidirectional/iteration.h"

#include <tbb/combinable.h>
#include <tbb/parallel_for.h>

namespace render::bidirectional {

Rgb Iteration::vpl_connection(const LightVertex& lv, const Vertex& v, const Vec3& wo, float clamp2,
                              Rng& rng, RenderStats& stats) const {
    const LightVertex& w = lv;
    Vec3 d = w.p - v.p;
    const float dist2 = length_squared(d);
    if (!(dist2 > 0)) return Rgb(0.0f);
    d = d / std::sqrt(dist2);
    const Rgb eye_f = v.f(wo, d);
    if (eye_f.is_black()) return Rgb(0.0f);
    const Rgb light_f = w.f(lv.wo, -d);
    if (light_f.is_black()) return Rgb(0.0f);
    // A VPL connection is the only technique for its paths: weight 1, and the estimator
    // averages over the N_L light paths of the iteration.
    const float geometry =
        v.shading_cos(d) * w.shading_cos(d) / std::max(dist2, clamp2) * plan_.vpl_scale;
    const Rgb contribution = eye_f * light_f * geometry;
    if (contribution.is_black()) return Rgb(0.0f);
    const Ray ray = scene_.spawn_ray_to(v.p, v.n, w.p, w.n());
    const Link l = link(ray, v.medium_toward(d), v.in_medium(), w.in_medium(), rng, stats);
    return contribution * visibility(l, ray, stats);
}

std::optional<Iteration::Record> Iteration::trace_record(uint64_t index, RenderStats& stats) const {
    Rng rng(StreamKey{key_.seed, key_.frame, key_.iteration, kRecordStreamBase + index});
    const Vec2 u = rng.next_2d();
    return trace_record_at(Vec2(u.x * float(camera_.width()), u.y * float(camera_.height())), rng,
                           stats);
}

std::optional<Iteration::Record> Iteration::trace_record_at(Vec2 position, Rng& rng,
                                                            RenderStats& stats) const {
    std::vector<Record> records;
    trace_records_at(position, 1, rng, stats, records);
    if (records.empty()) return std::nullopt;
    return std::move(records.front());
}

void Iteration::trace_records_at(Vec2 position, int count, Rng& rng, RenderStats& stats,
                                 std::vector<Record>& out) const {
    const size_t wanted = out.size() + size_t(count);
    Ray ray = camera_.sample_ray(position, rng);
    const Vec3 camera_direction = ray.direction, camera_origin = ray.origin;
    SubpathState state;
    state.throughput = Rgb(1.0f);
    state.mis = mis_.start_camera(camera_pixel_pdf_w(ray.origin, ray.direction));
    state.medium = scene_.camera_medium();
    float distance = 0;
    for (;; ++state.path_length) {
        SampledSegment seg;
        std::optional<SubpathVertex> v =
            next_vertex(ray, TransportMode::Radiance, rng, state, stats, seg);
        if (!v || state.path_length >= plan_.max_length) return;
        distance += seg.distance;
        if (v->has_non_delta()) {
            out.push_back(Record{*v, -ray.direction, state.throughput, state.path_length, distance,
                                 camera_direction, state.mis, camera_origin});
            if (out.size() == wanted) return;
        }
        if (!sample_scattering(*v, -ray.direction, rng, state, ray)) return;
    }
}

std::vector<double> Iteration::estimate_vpl_importance(RenderStats& stats) const {
    std::vector<Record> records;
    for (int j = 0; j < plan_.vpl_importance.records; ++j)
        if (std::optional<Record> r = trace_record(uint64_t(j), stats)) records.push_back(*r);
    const float clamp2 = record_clamp2();
    std::vector<double> phi(light_vertices_.size(), 0.0);
    tbb::combinable<RenderStats> local_stats;
    using Range = tbb::blocked_range<size_t>;
    tbb::parallel_for(Range(0, light_vertices_.size()), [&](const Range& range) {
        RenderStats& local = local_stats.local();
        for (size_t k = range.begin(); k < range.end(); ++k) {
            const LightVertex& lv = light_vertices_[k];
            Rng rng(StreamKey{key_.seed, key_.frame, key_.iteration, kImportanceStreamBase + k});
            double sum = 0;
            for (const Record& r : records) {
                if (lv.path_length + 1 + r.path_length > plan_.max_length) continue;
                const Rgb c = r.throughput * lv.throughput *
                              vpl_connection(lv, r.vertex, r.wo, clamp2, rng, local);
                const double y = c.luminance();
                if (std::isfinite(y) && y > 0) sum += y;
            }
            phi[k] = sum / double(plan_.vpl_importance.records);
        }
    });
    local_stats.combine_each([&](const RenderStats& s) { stats += s; });
    return phi;
}

void Iteration::select_vpls(RenderStats& stats, VplSelection* inspection) {
    const size_t candidates = light_vertices_.size();
    stats.vpl_candidates += candidates;
    if (candidates == 0) return;
    const std::vector<double> phi = estimate_vpl_importance(stats);
    // Keep candidate k with P_k (fixed before any draw, so E[kept / P_k] = 1 for each k).
    const std::vector<double> keep =
        vpl_keep_probabilities(phi, plan_.vpl_importance.min_probability);
    BlockVector<LightVertex> kept;
    for (size_t k = 0; k < candidates; ++k) {
        const double p = keep[k];
        Rng rng(StreamKey{key_.seed, key_.frame, key_.iteration, kAcceptStreamBase + k});
        const bool accepted = p >= 1.0 || double(rng.next_1d()) < p;
        if (inspection) {
            const LightVertex& lv = light_vertices_[k];
            inspection->candidates.push_back(VplCandidate{lv.p, lv.n(), lv.wo, lv.bsdf(),
                                                          lv.throughput, lv.path_length, phi[k], p,
                                                          accepted});
        }
        if (!accepted) continue;
        LightVertex v = light_vertices_[k];
        v.throughput = v.throughput * float(1.0 / p);
        kept.push_back(std::move(v));
    }
    stats.vpl_accepted += kept.size();
    light_vertices_ = std::move(kept);
    path_ends_.clear();  // vpl connects to every vertex; paths are no longer needed
}

}  // namespace render::bidirectional
