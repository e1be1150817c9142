// Importance caching (ic, and bpt's ic connections): the records' tables over the light
// vertices, and the draw of light vertices from the mixtures of the nearest records.
#include "core/integrators/bidirectional/iteration.h"

#include <tbb/blocked_range.h>
#include <tbb/combinable.h>
#include <tbb/parallel_for.h>

namespace render::bidirectional {

IcRecordTables Iteration::record_tables(const Record& r, float radius,
                                        std::span<const uint8_t> mask, Rng& rng,
                                        RenderStats& stats) const {
    const size_t m = ic_vertex_count_;
    std::vector<double> full(m, 0.0), unoccluded(m, 0.0), bounded(m, 0.0);
    const float clamp2 = record_clamp2();
    for (size_t k = 0; k < m; ++k) {
        const LightVertex& lv = light_vertices_[k];
        if (lv.path_length + 1 + r.path_length > plan_.max_length) continue;
        if (plan_.ic_connections) {
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
                                                lv.shading_cos(d), r.vertex.shading_cos(d));
            full[k] = y * double(visibility(t->link, t->ray, stats).luminance());
            continue;
        }
        const std::optional<ConnectionGeometry> g = connection_geometry(lv, r.vertex, r.wo);
        if (!g) continue;
        const double cos_record = r.vertex.shading_cos(g->d), cos_vpl = lv.shading_cos(g->d);
        const double power = (lv.throughput * g->eye.f * g->light.f).luminance();
        if (!(power > 0) || !std::isfinite(power)) continue;
        // The records' own clamp (at least 1 % of the scene radius): a VPL lying on the record
        // must not take the whole table. Tables shape the variance only (C covers every VPL).
        unoccluded[k] = power * cos_record * cos_vpl / std::max(double(g->dist2), double(clamp2));
        bounded[k] = power * bounded_geometry_factor(std::sqrt(double(g->dist2)), radius, cos_vpl,
                                                     cos_record);
        const Ray ray = scene_.spawn_ray_to(r.vertex.p, r.vertex.n, lv.p, lv.n());
        const Link l = link(ray, r.vertex.medium_toward(g->d), false, false, rng, stats);
        full[k] = unoccluded[k] * double(visibility(l, ray, stats).luminance());
    }
    return make_record_tables(full, unoccluded, bounded, mask);
}

void Iteration::build_importance_cache(RenderStats& stats) {
    // Paths are concatenated in order, so the first plan_.ic_light_path_count paths' vertices are a
    // prefix of light_vertices_.
    ic_vertex_count_ = path_ends_.empty() ? 0 : path_ends_[plan_.ic_light_path_count - 1];
    const size_t m = ic_vertex_count_;
    path_ends_.clear();  // importance caching draws from the cached vertices; no paths needed
    ic_weighting_.heuristic = plan_.cache.heuristic;
    if (plan_.cache.power_only) {
        // The baseline the paper compares with: no records; every shading point draws all
        // 4 n of its VPLs from one distribution proportional to the VPLs' power (its C slot:
        // with no record, the mixture is the fallback alone).
        std::vector<double> power(m);
        for (size_t k = 0; k < m; ++k) power[k] = light_vertices_[k].throughput.luminance();
        ic_fallback_ = ImportanceTable(power);
        ic_samples_ = IcSampleCounts{{0, 0, 0, 4 * plan_.cache.samples}};
        return;
    }
    // C: every VPL that carries power, the same mask at every record and in the fallback (a
    // VPL with h(x, v) > 0 anywhere is in it), which keeps the estimator unbiased.
    std::vector<uint8_t> mask(m);
    for (size_t k = 0; k < m; ++k) mask[k] = !light_vertices_[k].throughput.is_black();
    ic_fallback_ = conservative_table(mask);
    ic_samples_ = IcSampleCounts{
        {plan_.cache.samples, plan_.cache.samples, plan_.cache.samples, plan_.cache.samples}};
    ic_lookup_.lambda = ic_default_lambda(2.0 * scene_.bounding_sphere().radius);
    if (m == 0) return;

    // The jittered screen grid: square cells of 1 / density pixels, thinned (larger cells) if
    // the tables would exceed kIcTableBytes.
    // ic shades only the first non-delta eye vertex; bpt connects at every eye vertex, so its
    // record paths go on and hold records at their first few non-delta vertices.
    const int per_path = plan_.ic_connections ? kIcConnectionRecordsPerPath : 1;
    const int width = camera_.width(), height = camera_.height();
    const double table_bytes = 4.0 * double(m + 1) * sizeof(double) * per_path;
    // The density counts records: bpt's record paths are per_path times sparser.
    double cell = 1.0 / std::sqrt(plan_.cache.record_density / per_path);
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
                        double(cell_w) * cell_h /
                        camera_pixel_pdf_w(r.camera_origin, r.camera_direction);
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
            // The normal faces the side the record was seen from (importance_lookup.h: shading
            // points behind a record do not use it).
            const Record& r = records[j][i];
            points.push_back(
                IcRecordPoint{r.vertex.p, dot(r.vertex.n, r.wo) < 0 ? -r.vertex.n : r.vertex.n});
        }
    }
    ic_tables_.resize(usable.size());
    const bool optimise = plan_.cache.optimise && plan_.cache.heuristic == IcHeuristic::AlphaMax;
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

void Iteration::draw_from_importance_caches(const Vertex& v, int eye_length, Rng& rng,
                                            FunctionRef<Rgb(const LightVertex&)> term,
                                            ContributionSink add) const {
    if (ic_vertex_count_ == 0 || ic_fallback_.empty()) return;
    const IcNeighbours near = ic_tree_.nearest(v.p, v.n, ic_lookup_);
    std::array<const IcRecordTables*, kIcMaxRecords> tables{};
    for (int i = 0; i < near.count; ++i) tables[size_t(i)] = &ic_tables_[near.index[size_t(i)]];
    const IcMixture mixture(
        std::span<const IcRecordTables* const>(tables.data(), size_t(near.count)), ic_fallback_);
    for (IcType t : kIcTypes) {
        if (mixture.empty(t)) continue;
        for (int s = 0; s < ic_samples_[t]; ++s) {
            const double u_record = double(rng.next_1d());
            const size_t k = mixture.sample(t, u_record, next_double(rng));
            const double factor = ic_sample_factor(t, mixture.pmfs(k), ic_samples_, ic_weighting_);
            const LightVertex& lv = light_vertices_[k];
            if (!(factor > 0) || lv.path_length + 1 + eye_length > plan_.max_length) continue;
            add(lv.path_length + 1, term(lv) * float(factor));
        }
    }
}

}  // namespace render::bidirectional
