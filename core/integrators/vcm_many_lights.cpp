// Many-light rendering in the bidirectional family's Iteration: VPL connections, the
// importance-driven VPL selection and importance caching.

#include "core/integrators/vcm_iteration.h"

#include <tbb/blocked_range.h>
#include <tbb/combinable.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_pipeline.h>
#include <tbb/task_arena.h>

namespace render::vcm_detail {

Rgb Iteration::vpl_connection(const LightVertex& lv, const Vertex& v, const Vec3& wo, float clamp2,
                              Rng& rng, RenderStats& stats) const {
    const std::optional<ConnectionGeometry> g = connection_geometry(lv, v, wo);
    if (!g) return Rgb(0.0f);
    const Vertex& w = lv.vertex;
    const Vec3& d = g->d;
    // A VPL connection is the only technique for its paths: weight 1, and the estimator
    // averages over the N_L light paths of the iteration.
    const float geometry =
        v.shading_cos(d) * w.shading_cos(d) / std::max(g->dist2, clamp2) * vpl_scale_;
    const Rgb contribution = g->eye.f * g->light.f * geometry;
    if (contribution.is_black()) return Rgb(0.0f);
    const Ray ray = scene_.spawn_ray_to(v.p, v.n, w.p, w.n);
    const Link l = link(ray, v.medium_toward(wo, d), v.in_medium(), w.in_medium(), rng, stats);
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
    Ray ray = camera_.generate_ray(position);
    const Vec3 camera_direction = ray.direction;
    SubpathState state;
    state.throughput = Rgb(1.0f);
    state.mis = mis_.start_camera(camera_pixel_pdf_w(ray.direction));
    state.medium = scene_.camera_medium();
    float distance = 0;
    for (;; ++state.path_length) {
        SampledSegment seg;
        std::optional<SubpathVertex> v =
            next_vertex(ray, TransportMode::Radiance, rng, state, stats, seg);
        if (!v || state.path_length >= max_length_) return;
        distance += seg.distance;
        if (v->has_non_delta()) {
            out.push_back(Record{*v, -ray.direction, state.throughput, state.path_length, distance,
                                 camera_direction, state.mis});
            if (out.size() == wanted) return;
        }
        if (!sample_scattering(*v, -ray.direction, rng, state, ray)) return;
    }
}

std::vector<double> Iteration::estimate_vpl_importance(RenderStats& stats) const {
    std::vector<Record> records;
    for (int j = 0; j < config_.importance_records; ++j)
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
                if (lv.path_length + 1 + r.path_length > max_length_) continue;
                const Rgb c = r.throughput * lv.throughput *
                              vpl_connection(lv, r.vertex, r.wo, clamp2, rng, local);
                const double y = c.luminance();
                if (std::isfinite(y) && y > 0) sum += y;
            }
            phi[k] = sum / double(config_.importance_records);
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
    const std::vector<double> keep = vpl_keep_probabilities(phi, config_.vpl_min_probability);
    BlockVector<LightVertex> kept;
    for (size_t k = 0; k < candidates; ++k) {
        const double p = keep[k];
        Rng rng(StreamKey{key_.seed, key_.frame, key_.iteration, kAcceptStreamBase + k});
        const bool accepted = p >= 1.0 || double(rng.next_1d()) < p;
        if (inspection) {
            const LightVertex& lv = light_vertices_[k];
            inspection->candidates.push_back(VplCandidate{lv.vertex.p, lv.vertex.n, lv.wo,
                                                          lv.vertex.bsdf, lv.throughput,
                                                          lv.path_length, phi[k], p, accepted});
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

IcRecordTables Iteration::record_tables(const Record& r, float radius,
                                        std::span<const uint8_t> mask, Rng& rng,
                                        RenderStats& stats) const {
    const size_t m = ic_vertex_count_;
    std::vector<double> full(m, 0.0), unoccluded(m, 0.0), bounded(m, 0.0);
    const float clamp2 = record_clamp2();
    for (size_t k = 0; k < m; ++k) {
        const LightVertex& lv = light_vertices_[k];
        if (lv.path_length + 1 + r.path_length > max_length_) continue;
        if (ic_connections_) {
            // bpt: the table entries are the connection's own MIS-weighted contribution at the
            // record (the weight tames the 1 / d^2 of nearby vertices, so no clamp).
            const std::optional<ConnectionTerms> t =
                connection_terms(lv, Joint2Vertex{}, r.vertex, r.wo, r.mis, rng, stats);
            if (!t) continue;
            const double y = (lv.throughput * t->unoccluded).luminance();
            if (!(y > 0) || !std::isfinite(y)) continue;
            const Vec3& d = t->geometry.d;
            const double power =
                (lv.throughput * t->geometry.eye.f * t->geometry.light.f).luminance();
            unoccluded[k] = y;
            bounded[k] =
                power * bounded_geometry_factor(std::sqrt(double(t->geometry.dist2)), radius,
                                                lv.vertex.shading_cos(d), r.vertex.shading_cos(d));
            full[k] = y * double(visibility(t->link, t->ray, stats).luminance());
            continue;
        }
        const std::optional<ConnectionGeometry> g = connection_geometry(lv, r.vertex, r.wo);
        if (!g) continue;
        const double cos_record = r.vertex.shading_cos(g->d), cos_vpl = lv.vertex.shading_cos(g->d);
        const double power = (lv.throughput * g->eye.f * g->light.f).luminance();
        if (!(power > 0) || !std::isfinite(power)) continue;
        // The records' own clamp (at least 1 % of the scene radius): a VPL lying on the record
        // must not take the whole table. Tables shape the variance only (C covers every VPL).
        unoccluded[k] = power * cos_record * cos_vpl / std::max(double(g->dist2), double(clamp2));
        bounded[k] = power * bounded_geometry_factor(std::sqrt(double(g->dist2)), radius, cos_vpl,
                                                     cos_record);
        const Ray ray = scene_.spawn_ray_to(r.vertex.p, r.vertex.n, lv.vertex.p, lv.vertex.n);
        const Link l = link(ray, r.vertex.medium_toward(r.wo, g->d), false, false, rng, stats);
        full[k] = unoccluded[k] * double(visibility(l, ray, stats).luminance());
    }
    return make_record_tables(full, unoccluded, bounded, mask);
}

void Iteration::build_importance_cache(RenderStats& stats) {
    // Paths are concatenated in order, so the first ic_light_path_count_ paths' vertices are a
    // prefix of light_vertices_.
    ic_vertex_count_ = path_ends_.empty() ? 0 : path_ends_[ic_light_path_count_ - 1];
    const size_t m = ic_vertex_count_;
    path_ends_.clear();  // importance caching draws from the cached vertices; no paths needed
    ic_weighting_.heuristic = config_.ic_heuristic;
    if (config_.ic_power_only) {
        // The baseline the paper compares with: no records; every shading point draws all
        // 4 n of its VPLs from one distribution proportional to the VPLs' power (its C slot:
        // with no record, the mixture is the fallback alone).
        std::vector<double> power(m);
        for (size_t k = 0; k < m; ++k) power[k] = light_vertices_[k].throughput.luminance();
        ic_fallback_ = ImportanceTable(power);
        ic_samples_ = IcSampleCounts{{0, 0, 0, 4 * config_.ic_samples}};
        return;
    }
    // C: every VPL that carries power, the same mask at every record and in the fallback (a
    // VPL with h(x, v) > 0 anywhere is in it), which keeps the estimator unbiased.
    std::vector<uint8_t> mask(m);
    for (size_t k = 0; k < m; ++k) mask[k] = !light_vertices_[k].throughput.is_black();
    ic_fallback_ = conservative_table(mask);
    ic_samples_ = IcSampleCounts{
        {config_.ic_samples, config_.ic_samples, config_.ic_samples, config_.ic_samples}};
    ic_lookup_.lambda = ic_default_lambda(2.0 * scene_.bounding_sphere().radius);
    if (m == 0) return;

    // The jittered screen grid: square cells of 1 / density pixels, thinned (larger cells) if
    // the tables would exceed kIcTableBytes.
    // ic shades only the first non-delta eye vertex; bpt connects at every eye vertex, so its
    // record paths go on and hold records at their first few non-delta vertices.
    const int per_path = ic_connections_ ? kIcConnectionRecordsPerPath : 1;
    const int width = camera_.width(), height = camera_.height();
    const double table_bytes = 4.0 * double(m + 1) * sizeof(double) * per_path;
    // The density counts records: bpt's record paths are per_path times sparser.
    double cell = 1.0 / std::sqrt(config_.ic_record_density / per_path);
    cell = std::max(cell, std::sqrt(double(width) * height * table_bytes / kIcTableBytes));
    const int nx = std::max(1, int(std::ceil(width / cell))),
              ny = std::max(1, int(std::ceil(height / cell)));
    const float cell_w = float(width) / float(nx), cell_h = float(height) / float(ny);
    std::vector<std::vector<Record>> records(size_t(nx) * size_t(ny));
    std::vector<std::vector<float>> radii(records.size());
    tbb::combinable<RenderStats> local_stats;
    tbb::parallel_for(
        tbb::blocked_range<size_t>(0, records.size()),
        [&](const tbb::blocked_range<size_t>& range) {
            RenderStats& local = local_stats.local();
            for (size_t j = range.begin(); j < range.end(); ++j) {
                Rng rng(StreamKey{key_.seed, key_.frame, key_.iteration, kIcRecordStreamBase + j});
                const Vec2 u = rng.next_2d();
                const Vec2 position((float(j % nx) + u.x) * cell_w, (float(j / nx) + u.y) * cell_h);
                trace_records_at(position, per_path, rng, local, records[j]);
                for (const Record& r : records[j]) {
                    // The region of influence: the disk of the record's cell seen on its
                    // surface (cell solid angle x distance^2 / cos, as an area; along the
                    // path for deeper records, which ignores the spread of the scattering).
                    const double solid_angle =
                        double(cell_w) * cell_h / camera_pixel_pdf_w(r.camera_direction);
                    const double cos_in = std::max(0.1f, r.vertex.cos(r.wo));
                    radii[j].push_back(
                        float(std::sqrt(solid_angle * r.distance * r.distance / cos_in / kPi)));
                }
            }
        });
    std::vector<const Record*> usable;
    std::vector<float> usable_radii;
    std::vector<IcRecordPoint> points;
    for (size_t j = 0; j < records.size(); ++j) {
        for (size_t i = 0; i < records[j].size(); ++i) {
            usable.push_back(&records[j][i]);
            usable_radii.push_back(radii[j][i]);
            points.push_back(IcRecordPoint{records[j][i].vertex.p, records[j][i].vertex.n});
        }
    }
    ic_tables_.resize(usable.size());
    const bool optimise = config_.ic_optimise && config_.ic_heuristic == IcHeuristic::AlphaMax;
    tbb::parallel_for(
        tbb::blocked_range<size_t>(0, usable.size()), [&](const tbb::blocked_range<size_t>& range) {
            RenderStats& local = local_stats.local();
            for (size_t j = range.begin(); j < range.end(); ++j) {
                Rng rng(StreamKey{key_.seed, key_.frame, key_.iteration, kIcTableStreamBase + j});
                ic_tables_[j] = record_tables(*usable[j], usable_radii[j], mask, rng, local);
                if (optimise)
                    ic_tables_[j] =
                        optimise_record_tables(ic_tables_[j], ic_samples_, ic_weighting_.alpha);
            }
        });
    local_stats.combine_each([&](const RenderStats& s) { stats += s; });
    ic_tree_ = IcRecordTree(std::move(points));
}

}  // namespace render::vcm_detail
