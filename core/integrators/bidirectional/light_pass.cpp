// The light pass: light subpaths traced in chunks, in parallel, gathered in chunk order
// (their vertices, J2's light rays, the merging grids' positions), and their connections to the
// camera (t = 1).
#include "core/integrators/bidirectional/iteration.h"

#include <tbb/parallel_pipeline.h>
#include <tbb/task_arena.h>

namespace render::bidirectional {

// --- light subpaths ---------------------------------------------------------------------------

bool Iteration::generate_light_sample(Rng& rng, SubpathState& state, Ray& ray) const {
    float pick_probability = 0;
    const Light* light = scene_.sample_emitter(rng.next_1d(), &pick_probability);
    if (light && light->as_volume())
        return generate_volume_light_sample(*light->as_volume(), pick_probability, rng, state, ray);
    Vec2 u_position = rng.next_2d(), u_direction = rng.next_2d();
    LightEmitSample e;
    if (!light || !(pick_probability > 0) || !light->emit(u_position, u_direction, e)) return false;
    const float emission_pdf_w = e.pdf_emission_w * pick_probability;
    const float direct_pdf_a = e.pdf_direct_a * pick_probability;
    if (!(emission_pdf_w > 0)) return false;

    state.throughput = e.energy / emission_pdf_w;
    state.initial_luminance = std::max(state.throughput.max(), 1e-30f);
    state.path_length = 1;
    state.is_finite_light = light->is_finite();
    state.medium = light->is_finite() ? light->medium : nullptr;
    state.in_medium = false;
    // Infinite lights have no cosine at the (virtual) emission point; a delta light cannot be
    // hit, so no technique ends on it by chance (eqs. 31-33).
    state.mis = mis_.start_light(direct_pdf_a, emission_pdf_w,
                                 light->is_finite() ? e.cos_at_light : 1.0f, light->is_delta());
    state.origin = e.origin;
    // Offsetting along the direction keeps the ray off the emitting surface.
    ray = light->is_finite() ? scene_.spawn_ray(e.origin, e.direction, e.direction)
                             : Ray(e.origin, e.direction);
    return state.throughput.is_finite();
}

bool Iteration::generate_volume_light_sample(const VolumeEmitter& emitter, float pick_probability,
                                             Rng& rng, SubpathState& state, Ray& ray) const {
    const VolumeLightSample y = sample_volume_light_start(emitter, pick_probability, rng);
    if (!y.valid) return false;
    // Where light subpaths read the rule as camera paths do, y_0 emits as a point of the medium
    // it starts in, whatever its first direction meets: a first region that camera paths give
    // another medium stops the subpath at its far boundary (next_vertex), wherever the first
    // segment scatters (docs/design/media.md).
    const Rgb source = plan_.camera_medium_rule ? emitter.source_in_medium(y.p) : y.source;
    state.throughput = source / y.emission_pdf_w;
    state.initial_luminance = std::max(state.throughput.max(), 1e-30f);
    state.path_length = 1;
    state.is_finite_light = true;
    // y_0 is a medium vertex: the first segment starts inside the medium, without an offset.
    state.medium = emitter.medium;
    state.in_medium = true;
    // Eqs. (31)-(33) with cos = 1 and the volume density (docs/design/media.md).
    state.mis = start_volume_light_mis(mis_, y.direct_pdf_a);
    state.origin = y.p;
    ray = Ray(y.p, y.direction);
    return state.throughput.is_finite();
}

void Iteration::trace_light_path(uint64_t path_index, std::vector<LightVertex>& vertices,
                                 std::vector<Splat>& splats, RenderStats& stats,
                                 std::vector<LightRay>* rays, std::vector<Joint2Vertex>* joint2,
                                 std::vector<LightVertexMedia>* arrival_media) const {
    Rng rng(StreamKey{key_.seed, key_.frame, key_.iteration, kLightStreamBase + path_index});
    SubpathState state;
    Ray ray;
    if (!generate_light_sample(rng, state, ray)) return;
    // J2 joins a ray's resampled vertex (after path_length segments) to an eye vertex: rays whose
    // paths would exceed max_depth are not kept.
    if (rays && state.is_finite_light && 3 <= plan_.max_length)
        record_light_ray(ray, state, 1, *rays, stats);

    uint32_t beam_piece = 0;
    for (;; ++state.path_length) {
        SampledSegment seg;
        // Photon beams (from the first photon_beam_path_count paths) need the subpath as it was
        // before the segment.
        std::optional<SubpathState> before;
        if (plan_.photon_beams && path_index < plan_.photon_beam_path_count) before = state;
        std::optional<SubpathVertex> v =
            next_vertex(ray, TransportMode::Importance, rng, state, stats, seg);
        if (before) emit_photon_beams(ray, *before, seg, path_index, beam_piece, rng, stats);
        if (!v) break;
        const Vec3 wo = -ray.direction;
        // Delta BSDFs can neither be connected to nor merged at (the report's specular vertices).
        if (v->has_non_delta()) {
            if (plan_.vertex_connections || plan_.merging || plan_.many_lights()) {
                vertices.emplace_back(*v, wo, state.throughput, state.path_length, state.mis,
                                      state.is_finite_light);
                if (joint2) joint2->push_back(v->joint2);
                if (arrival_media)
                    arrival_media->push_back(
                        LightVertexMedia{v->medium, v->in_medium() ? nullptr : v->shape});
            }
            if ((plan_.vertex_connections || plan_.light_tracing_only) &&
                state.path_length + 1 <= plan_.max_length)
                connect_to_camera(state, *v, wo, rng, splats, stats);
        }
        // Extending needs one more segment plus at least the segment to the eye.
        if (state.path_length + 2 > plan_.max_length) break;
        if (!sample_scattering(*v, wo, rng, state, ray)) break;
        if (rays && state.path_length + 3 <= plan_.max_length)
            record_light_ray(ray, state, state.path_length + 1, *rays, stats);
    }
}

void Iteration::record_light_ray(const Ray& ray, const SubpathState& state, int path_length,
                                 std::vector<LightRay>& rays, RenderStats& stats) const {
    if (!state.medium || !state.medium->is_homogeneous()) return;
    // The ray's first piece (one closest hit per light ray).
    ++stats.rays;
    LightRay r;
    r.origin = state.origin;
    r.direction = ray.direction;
    r.throughput = state.throughput;
    r.mis = state.mis;
    r.medium = state.medium;
    r.piece_end = dot(ray.origin - state.origin, ray.direction) + scene_.closest_hit_distance(ray);
    r.origin_previous = state.origin_previous;
    r.origin_previous2 = state.origin_previous2;
    r.origin_light_ray_pdf = state.origin_light_ray_pdf;
    r.origin_previous_light_ray_pdf = state.origin_previous_light_ray_pdf;
    r.carried_connection = state.carried_connection;
    r.path_length = path_length;
    r.origin_in_medium = state.origin_in_medium;
    r.finite_light = state.is_finite_light;
    rays.push_back(r);
}

void Iteration::trace_light_paths(RenderStats& stats, const SplatSink& add_splats) {
    const uint64_t chunks = (plan_.light_path_count + kLightPathChunk - 1) / kLightPathChunk;
    // Chunk buffers: cleared, their capacity kept from the last iteration.
    std::vector<LightChunk*>& free_chunks = storage_.free_light_chunks;
    free_chunks.clear();
    for (const std::unique_ptr<LightChunk>& c : storage_.light_chunks)
        free_chunks.push_back(c.get());
    auto take_chunk = [&] {
        std::lock_guard lock(storage_.light_chunks_mutex);
        if (free_chunks.empty()) {
            storage_.light_chunks.push_back(std::make_unique<LightChunk>());
            return storage_.light_chunks.back().get();
        }
        LightChunk* chunk = free_chunks.back();
        free_chunks.pop_back();
        return chunk;
    };
    auto give_back = [&](LightChunk* chunk) {
        std::lock_guard lock(storage_.light_chunks_mutex);
        free_chunks.push_back(chunk);
    };

    path_ends_.reserve(plan_.light_path_count);
    uint64_t next_chunk = 0;
    auto next = [&](tbb::flow_control& control) -> LightChunk* {
        if (next_chunk == chunks) {
            control.stop();
            return nullptr;
        }
        LightChunk* chunk = take_chunk();
        chunk->index = next_chunk++;
        return chunk;
    };
    auto trace = [&](LightChunk* chunk) {
        chunk->vertices.clear();
        chunk->path_sizes.clear();
        chunk->light_rays.clear();
        chunk->ray_counts.clear();
        chunk->joint2_vertices.clear();
        chunk->arrival_media.clear();
        chunk->splats.clear();
        chunk->stats = RenderStats{};
        const uint64_t first = chunk->index * kLightPathChunk;
        const uint64_t last = std::min(first + kLightPathChunk, plan_.light_path_count);
        for (uint64_t p = first; p < last; ++p) {
            const size_t before = chunk->vertices.size(), rays_before = chunk->light_rays.size();
            trace_light_path(p, chunk->vertices, chunk->splats, chunk->stats,
                             plan_.joint2 ? &chunk->light_rays : nullptr,
                             plan_.joint2 ? &chunk->joint2_vertices : nullptr,
                             plan_.camera_medium_rule ? &chunk->arrival_media : nullptr);
            chunk->path_sizes.push_back(uint32_t(chunk->vertices.size() - before));
            if (plan_.joint2)
                chunk->ray_counts.push_back(uint32_t(chunk->light_rays.size() - rays_before));
        }
        return chunk;
    };
    uint32_t end = 0;
    auto gather = [&](LightChunk* chunk) {
        for (uint32_t size : chunk->path_sizes) path_ends_.push_back(end += size);
        uint32_t ray_end = uint32_t(light_rays_.size());
        for (uint32_t count : chunk->ray_counts) ray_ends_.push_back(ray_end += count);
        light_rays_.insert(light_rays_.end(), chunk->light_rays.begin(), chunk->light_rays.end());
        for (const Joint2Vertex& j : chunk->joint2_vertices) joint2_vertices_.push_back(j);
        for (const LightVertexMedia& m : chunk->arrival_media) light_vertex_media_.push_back(m);
        for (LightVertex& v : chunk->vertices) {
            if (plan_.merging) {
                const bool medium = v.in_medium();
                if (medium) medium_positions_.push_back(v.p);
                (medium ? medium_index_ : surface_index_)
                    .push_back(uint32_t(light_vertices_.size()));
            }
            light_vertices_.push_back(std::move(v));
        }
        add_splats(chunk->splats);
        stats += chunk->stats;
        give_back(chunk);
    };
    // Gathering runs on one thread at a time, in chunk order (deterministic whatever the thread
    // count), while the other threads go on tracing later chunks.
    const size_t in_flight =
        size_t(kLightChunksInFlightPerThread) * size_t(tbb::this_task_arena::max_concurrency());
    tbb::parallel_pipeline(
        in_flight,
        tbb::make_filter<void, LightChunk*>(tbb::filter_mode::serial_in_order, next) &
            tbb::make_filter<LightChunk*, LightChunk*>(tbb::filter_mode::parallel, trace) &
            tbb::make_filter<LightChunk*, void>(tbb::filter_mode::serial_in_order, gather));

    if (plan_.merging) {
        // Each grid point carries its light vertex's index: a merge goes from the point straight
        // to the vertex (the index arrays are increasing, so the visiting order is unchanged).
        surface_grid_.build(
            surface_index_.size(), [&](size_t i) { return light_vertices_[surface_index_[i]].p; },
            plan_.radius, surface_index_);
        medium_grid_.build(medium_positions_, plan_.volume_radius, medium_index_);
    }
    if (plan_.query_beams) {
        if (!storage_.beam_lookup) storage_.beam_lookup = std::make_unique<PointsAlongRay>();
        // The photon points of the first query_beam_path_count paths: a prefix (paths are
        // gathered in order, and medium_index_ increases).
        const uint32_t vertex_end =
            path_ends_.empty() || plan_.query_beam_path_count == 0
                ? 0
                : path_ends_[std::min<size_t>(plan_.query_beam_path_count, path_ends_.size()) - 1];
        const size_t points =
            size_t(std::lower_bound(medium_index_.begin(), medium_index_.end(), vertex_end) -
                   medium_index_.begin());
        storage_.beam_lookup->build(medium_positions_, float(plan_.beam_radius), points);
    }
    if (plan_.photon_beams) build_photon_beams();
}

void Iteration::connect_to_camera(const SubpathState& state, const SubpathVertex& v, const Vec3& wo,
                                  Rng& rng, std::vector<Splat>& splats, RenderStats& stats) const {
    // The pinhole, or a lens point sampled uniformly (its density cancels: perspective_camera.h).
    const std::optional<PerspectiveCamera::LensConnection> lens =
        camera_.sample_connection(v.p, rng);
    if (!lens) return;
    const Vec3 camera_point = lens->lens_point;
    const Vec2 raster = lens->raster;
    const Vec3 to_camera = camera_point - v.p;
    const float dist2 = length_squared(to_camera);
    if (!(dist2 > 0)) return;
    const Vec3 d = to_camera / std::sqrt(dist2);
    const auto [f, pdf_w] = v.evaluate(wo, d);
    if (f.is_black()) return;
    Ray ray = scene_.spawn_ray_to(v.p, v.n, camera_point, Vec3());
    Link l = link(ray, v.medium_toward(d), v.in_medium(), false, rng, stats);
    // The camera's distance density of this vertex through the media on the way.
    float camera_distance = l.densities.toward_start;
    if (plan_.camera_medium_rule &&
        (l.against_declaration || l.end_medium != scene_.camera_medium())) {
        // This link reads the medium rule differently from the camera: read it from the camera
        // (docs/design/media.md, "Which medium a path is in"). Where the light subpath's last
        // region goes on through v, the camera must reach v in the medium the subpath gave it.
        ray = scene_.spawn_ray_to(camera_point, Vec3(), v.p, v.n);
        l = link(ray, scene_.camera_medium(), false, v.in_medium(), rng, stats);
        if (v.keeps_medium() && l.end_medium != v.medium) return;
        camera_distance = l.densities.toward_end;
    }
    if (l.traced && l.transmittance.is_black()) return;
    const float camera_pdf_w = camera_pixel_pdf_w(camera_point, -d);
    // The camera's density of this vertex (eq. 46), through the media on the way.
    const float camera_pdf_a = camera_pdf_w * v.cos(d) * camera_distance / dist2;
    // J1 of the junction whose eye-side vertex is this one, sampled along the camera ray.
    float light_joint_ratio = 0;
    if (plan_.joint && v.in_medium() &&
        joint_light_side(state.path_length, state.is_finite_light) && l.one_piece &&
        camera_distance > 0)
        light_joint_ratio = joint_pdf_l(camera_point, v.p, v.previous) / camera_distance;
    const float camera_light_joint2 =
        light_joint_ratio > 0
            ? light_joint2_ratio(v.joint2.previous2, v.previous, v.joint2.previous_light_ray_pdf,
                                 camera_point, v.p)
            : 0.0f;
    // P-B2D at this vertex with the camera ray as the query.
    const float light_query_beam =
        v.in_medium()
            ? mis_.query_beam_term(camera_pdf_w * v.cos(d) / dist2 / float(plan_.light_path_count))
            : 0.0f;
    // B-B1D at this vertex, the camera ray as the query.
    const float light_photon_beam = light_photon_beam_term(
        v, wo, d, camera_pdf_w * v.cos(d) / dist2 / float(plan_.light_path_count));
    const float weight =
        plan_.light_tracing_only
            ? 1.0f
            : mis_.weight_camera(state.mis, {.camera_pdf_a = camera_pdf_a,
                                             .light_reverse_w = pdf_w.reverse,
                                             .light_medium = v.in_medium(),
                                             .light_query_beam = light_query_beam,
                                             .light_joint_ratio = light_joint_ratio,
                                             .light_joint2_ratio = camera_light_joint2,
                                             .light_photon_beam = light_photon_beam});
    const Rgb contribution =
        state.throughput * f *
        (weight * camera_pdf_w * v.shading_cos(d) / (dist2 * float(plan_.light_path_count)));
    if (contribution.is_black()) return;
    const Rgb tr = visibility(l, ray, stats);
    if (tr.is_black()) return;
    const uint32_t x = std::min(uint32_t(raster.x), uint32_t(camera_.width() - 1));
    const uint32_t y = std::min(uint32_t(raster.y), uint32_t(camera_.height() - 1));
    splats.push_back(
        Splat{y * uint32_t(camera_.width()) + x, contribution * tr, state.path_length + 1});
}

}  // namespace render::bidirectional
