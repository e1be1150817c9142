#include "core/integrators/vertex_cm.h"

#include "core/integrators/vcm_iteration.h"

#include <tbb/blocked_range.h>
#include <tbb/combinable.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_pipeline.h>
#include <tbb/task_arena.h>

namespace render {
namespace vcm_detail {

// --- segments and links -----------------------------------------------------------------------

std::optional<SubpathVertex> Iteration::next_vertex(const Ray& ray, TransportMode mode, Rng& rng,
                                                    SubpathState& state, RenderStats& stats,
                                                    SampledSegment& seg) const {
    if (!state.medium && !scene_.has_media()) {
        // Surface-only scenes: one closest hit, every distance density 1 (as sample_segment
        // would return, without its bookkeeping).
        ++stats.rays;
        if (!scene_.intersect(ray, seg.si)) return std::nullopt;
        seg.end = SegmentEnd::Surface;
        seg.position = seg.si.p;
        seg.distance = seg.si.t;
    } else {
        seg = sample_segment(scene_, ray, state.medium, state.in_medium, rng, stats);
        // The eye collects emission at vertices of emitting media even where nothing scatters
        // (albedo 0); trace_eye_path ends the path after it.
        const bool collects_emission = mode == TransportMode::Radiance &&
                                       seg.end == SegmentEnd::Medium && seg.medium->is_emissive() &&
                                       !scene_.volume_lights().empty();
        if (collects_emission) state.source_throughput = state.throughput * seg.source_weight;
        state.throughput *= seg.weight;
        if (seg.end == SegmentEnd::Escaped || (state.throughput.is_black() && !collects_emission))
            return std::nullopt;
    }
    SubpathVertex v;
    v.p = seg.position;
    v.medium = seg.medium;
    v.previous = state.origin;
    v.joint2.previous2 = state.origin_previous;
    v.joint2.previous_light_ray_pdf = state.origin_light_ray_pdf;
    const Vec3 wo = -ray.direction;
    if (seg.end == SegmentEnd::Medium) {
        v.phase = &seg.medium->phase();
        if (seg.one_piece) v.joint_distance_pdf = seg.densities.toward_end;
        // J2's light-side vertex: a light subpath's medium vertex reached in one piece from a
        // scattering vertex or a finite light's point (record_light_ray keeps that ray).
        if (joint2_ && mode == TransportMode::Importance && seg.one_piece &&
            joint_light_side(state.path_length, state.is_finite_light) &&
            seg.medium->is_homogeneous())
            v.joint2.light_ray_pdf = seg.densities.toward_end;
        if (mode == TransportMode::Radiance)
            v.query_beam = mis_.query_beam_factor(seg.densities.toward_end);
        if (photon_beams_) set_photon_beam_quantities(v, seg, mode);
    } else {
        v.n = seg.si.geometric_normal;
        v.shape = seg.si.shape;
        v.bsdf.emplace(*seg.si.bsdf, seg.si.shading, seg.si.geometric_normal, mode);
    }
    const float cos_in = v.cos(wo);
    if (!(cos_in > 0)) return std::nullopt;
    // For infinite lights the first segment has no distance term.
    mis_.arrive(state.mis, seg.distance * seg.distance,
                state.path_length > 1 || state.is_finite_light, cos_in, seg.densities.toward_end,
                seg.densities.toward_start);
    // Light subpaths: the J1 technique of the junction whose eye-side vertex is the one this
    // segment left (a medium vertex whose light-side neighbour scatters, or is a finite light's
    // point: J1 at s = 1), sampled from here.
    if (joint_ && mode == TransportMode::Importance && state.carried_connection > 0 &&
        state.origin_in_medium && joint_light_side(state.path_length - 1, state.is_finite_light) &&
        seg.one_piece)
        mis_.add_joint_term(
            state.mis, state.carried_connection,
            joint_pdf_l(v.p, state.origin, state.origin_previous), cos_in, seg.densities.toward_end,
            light_joint2_ratio(state.origin_previous2, state.origin_previous,
                               state.origin_previous_light_ray_pdf, v.p, state.origin));
    if (mode == TransportMode::Radiance && seg.one_piece)
        add_arrival_joint2_term(state.mis, state, v.p, cos_in, seg.densities.toward_end);
    // Light subpaths: the P-B2D term of the vertex this segment left (the segment from here is
    // the query that covers it).
    if (mode == TransportMode::Importance)
        mis_.add_query_beam_term(state.mis, state.carried_query_beam, cos_in,
                                 seg.densities.toward_end);
    // Photon beams: the B-B1D term of the vertex this segment left (on eye subpaths, this
    // segment is the photon beam that reaches it).
    // Light subpaths: whether the vertex's own arrival can carry a beam is in its carried term
    // already (this segment is the long query, which needs no support).
    const bool eye = mode == TransportMode::Radiance;
    mis_.add_photon_beam_term(state.mis, state.carried_photon_beam, cos_in,
                              seg.densities.toward_end, seg.densities.toward_start, eye,
                              !eye || beam_segment(seg.densities));
    return v;
}

Link Iteration::link(const Ray& ray, const Medium* medium, bool start_in_medium, bool end_in_medium,
                     Rng& rng, RenderStats& stats) const {
    if (!scene_.has_media()) return Link{};
    const SegmentConnection c =
        connect_segment(scene_, ray, medium, start_in_medium, end_in_medium, rng, stats);
    return Link{c.densities, c.transmittance, true, c.one_piece};
}

Rgb Iteration::visibility(const Link& l, const Ray& ray, RenderStats& stats) const {
    if (l.traced) return l.transmittance;
    ++stats.rays;
    return scene_.occluded(ray) ? Rgb(0.0f) : Rgb(1.0f);
}

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
    state.throughput = y.source / y.emission_pdf_w;
    state.initial_luminance = std::max(state.throughput.max(), 1e-30f);
    state.path_length = 1;
    state.is_finite_light = true;
    // y_0 is a medium vertex: the first segment starts inside the medium, without an offset.
    state.medium = emitter.medium;
    state.in_medium = true;
    // Eqs. (31)-(33) with cos = 1 and the volume density (docs/media.md).
    state.mis = start_volume_light_mis(mis_, y.direct_pdf_a);
    state.origin = y.p;
    ray = Ray(y.p, y.direction);
    return state.throughput.is_finite();
}

void Iteration::trace_light_path(uint64_t path_index, std::vector<LightVertex>& vertices,
                                 std::vector<Splat>& splats, RenderStats& stats,
                                 std::vector<LightRay>* rays,
                                 std::vector<Joint2Vertex>* joint2) const {
    Rng rng(StreamKey{key_.seed, key_.frame, key_.iteration, kLightStreamBase + path_index});
    SubpathState state;
    Ray ray;
    if (!generate_light_sample(rng, state, ray)) return;
    // J2 joins a ray's resampled vertex (after path_length segments) to an eye vertex: rays whose
    // paths would exceed max_depth are not kept.
    if (rays && state.is_finite_light && 3 <= max_length_)
        record_light_ray(ray, state, 1, *rays, stats);

    uint32_t beam_piece = 0;
    for (;; ++state.path_length) {
        SampledSegment seg;
        // Photon beams need the subpath as it was before the segment.
        std::optional<SubpathState> before;
        if (photon_beams_) before = state;
        std::optional<SubpathVertex> v =
            next_vertex(ray, TransportMode::Importance, rng, state, stats, seg);
        if (before) emit_photon_beams(ray, *before, seg, path_index, beam_piece, rng, stats);
        if (!v) break;
        const Vec3 wo = -ray.direction;
        // Delta BSDFs can neither be connected to nor merged at (the report's specular vertices).
        if (v->has_non_delta()) {
            if (use_vc_ || use_vm_ || many_lights_) {
                vertices.push_back(LightVertex{.wo = wo,
                                               .throughput = state.throughput,
                                               .path_length = state.path_length,
                                               .mis = state.mis,
                                               .vertex = *v,
                                               .finite_light = state.is_finite_light});
                if (joint2) joint2->push_back(v->joint2);
            }
            if ((use_vc_ || light_trace_only_) && state.path_length + 1 <= max_length_)
                connect_to_camera(state, *v, wo, rng, splats, stats);
        }
        // Extending needs one more segment plus at least the segment to the eye.
        if (state.path_length + 2 > max_length_) break;
        if (!sample_scattering(*v, wo, rng, state, ray)) break;
        if (rays && state.path_length + 3 <= max_length_)
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
    const uint64_t chunks = (light_path_count_ + kLightPathChunk - 1) / kLightPathChunk;
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

    path_ends_.reserve(light_path_count_);
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
        chunk->splats.clear();
        chunk->stats = RenderStats{};
        const uint64_t first = chunk->index * kLightPathChunk;
        const uint64_t last = std::min(first + kLightPathChunk, light_path_count_);
        for (uint64_t p = first; p < last; ++p) {
            const size_t before = chunk->vertices.size(), rays_before = chunk->light_rays.size();
            trace_light_path(p, chunk->vertices, chunk->splats, chunk->stats,
                             joint2_ ? &chunk->light_rays : nullptr,
                             joint2_ ? &chunk->joint2_vertices : nullptr);
            chunk->path_sizes.push_back(uint32_t(chunk->vertices.size() - before));
            if (joint2_)
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
        for (LightVertex& v : chunk->vertices) {
            if (use_vm_) {
                const bool medium = v.vertex.in_medium();
                (medium ? medium_positions_ : surface_positions_).push_back(v.vertex.p);
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

    if (use_vm_) {
        // Each grid point carries its light vertex's index: a merge goes from the point straight
        // to the vertex (the index arrays are increasing, so the visiting order is unchanged).
        surface_grid_.build(surface_positions_, radius_, surface_index_);
        medium_grid_.build(medium_positions_, volume_radius_, medium_index_);
    }
    if (query_beams_) {
        if (!storage_.beam_lookup) storage_.beam_lookup = std::make_unique<PointsAlongRay>();
        storage_.beam_lookup->build(medium_positions_, float(beam_radius_));
    }
    if (photon_beams_) build_photon_beams();
}

bool Iteration::sample_scattering(const SubpathVertex& v, const Vec3& wo, Rng& rng,
                                  SubpathState& state, Ray& ray) const {
    const float u_lobe = rng.next_1d();
    const Vec2 u = rng.next_2d();
    std::optional<BsdfSample> bs = v.sample(wo, u_lobe, u);
    if (!bs || bs->weight.is_black()) return false;
    const float cos_out = v.cos(bs->wi);
    if (!(cos_out > 0)) return false;

    if (!bs->delta && !(bs->pdf_w.forward > 0)) return false;
    if (joint_)
        state.carried_connection =
            mis_.carried_connection_term(state.mis, cos_out, bs->pdf_w.forward, bs->delta);
    // Eye subpaths (J2): the J1 share of the term this scatter adds, completed at the next
    // arrival (add_arrival_joint2_term; light subpaths ignore it).
    state.carried_eye_joint2 =
        joint2_ && v.in_medium() && v.medium->is_homogeneous()
            ? mis_.carried_eye_joint2_term(state.mis, v.camera_joint_ratio, cos_out,
                                           bs->pdf_w.forward, bs->delta)
            : 0.0f;
    state.carried_query_beam =
        v.in_medium() ? mis_.carried_query_beam_term(cos_out, bs->pdf_w.forward, bs->delta) : 0.0f;
    if (photon_beams_)
        state.carried_photon_beam =
            v.in_medium() ? mis_.carried_photon_beam_term(cos_out, bs->pdf_w.forward, bs->delta,
                                                          length(cross(wo, bs->wi)), v.photon_beam)
                          : 0.0f;
    // Eqs. (34)-(36); Russian roulette below is deliberately not part of the densities.
    mis_.scatter(state.mis, cos_out, bs->pdf_w.forward, bs->pdf_w.reverse, bs->delta, v.in_medium(),
                 v.query_beam);
    state.origin_previous2 = state.origin_previous;
    state.origin_previous_light_ray_pdf = state.origin_light_ray_pdf;
    state.origin_light_ray_pdf = v.joint2.light_ray_pdf;
    state.origin = v.p;
    state.origin_previous = v.previous;
    state.origin_joint_pdf = v.joint_distance_pdf;
    state.origin_in_medium = v.in_medium();
    state.specular_path = state.specular_path && bs->delta;
    state.throughput *= bs->weight;

    if (state.path_length >= config_.rr_depth) {
        const float q = std::min(0.95f, state.throughput.max() / state.initial_luminance);
        if (!(q > 0) || rng.next_1d() >= q) return false;
        state.throughput *= 1.0f / q;
    }
    state.medium = v.medium_toward(wo, bs->wi);
    state.in_medium = v.in_medium();
    ray = v.in_medium() ? Ray(v.p, bs->wi) : scene_.spawn_ray(v.p, v.n, bs->wi);
    return true;
}

void Iteration::connect_to_camera(const SubpathState& state, const SubpathVertex& v, const Vec3& wo,
                                  Rng& rng, std::vector<Splat>& splats, RenderStats& stats) const {
    std::optional<Vec2> raster = camera_.raster_position(v.p);
    if (!raster) return;
    const Vec3 to_camera = camera_.position() - v.p;
    const float dist2 = length_squared(to_camera);
    if (!(dist2 > 0)) return;
    const Vec3 d = to_camera / std::sqrt(dist2);
    const auto [f, pdf_w] = v.evaluate(wo, d);
    if (f.is_black()) return;
    const Ray ray = scene_.spawn_ray_to(v.p, v.n, camera_.position(), Vec3());
    const Link l = link(ray, v.medium_toward(wo, d), v.in_medium(), false, rng, stats);
    if (l.traced && l.transmittance.is_black()) return;
    const float camera_pdf_w = camera_pixel_pdf_w(-d);
    // The camera's density of this vertex (eq. 46), through the media on the way.
    const float camera_pdf_a = camera_pdf_w * v.cos(d) * l.densities.toward_start / dist2;
    // J1 of the junction whose eye-side vertex is this one, sampled along the camera ray.
    float light_joint_ratio = 0;
    if (joint_ && v.in_medium() && joint_light_side(state.path_length, state.is_finite_light) &&
        l.one_piece && l.densities.toward_start > 0)
        light_joint_ratio =
            joint_pdf_l(camera_.position(), v.p, v.previous) / l.densities.toward_start;
    const float camera_light_joint2 =
        light_joint_ratio > 0
            ? light_joint2_ratio(v.joint2.previous2, v.previous, v.joint2.previous_light_ray_pdf,
                                 camera_.position(), v.p)
            : 0.0f;
    // P-B2D at this vertex with the camera ray as the query.
    const float light_query_beam =
        v.in_medium()
            ? mis_.query_beam_term(camera_pdf_w * v.cos(d) / dist2 / float(light_path_count_))
            : 0.0f;
    // B-B1D at this vertex, the camera ray as the query.
    const float light_photon_beam = light_photon_beam_term(
        v, wo, d, camera_pdf_w * v.cos(d) / dist2 / float(light_path_count_));
    const float weight =
        light_trace_only_
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
        (weight * camera_pdf_w * v.shading_cos(d) / (dist2 * float(light_path_count_)));
    if (contribution.is_black()) return;
    const Rgb tr = visibility(l, ray, stats);
    if (tr.is_black()) return;
    const uint32_t x = std::min(uint32_t(raster->x), uint32_t(camera_.width() - 1));
    const uint32_t y = std::min(uint32_t(raster->y), uint32_t(camera_.height() - 1));
    splats.push_back(
        Splat{y * uint32_t(camera_.width()) + x, contribution * tr, state.path_length + 1});
}

// --- eye subpaths -----------------------------------------------------------------------------

Rgb Iteration::emission(const Light* light, const SubpathState& state, const Vec3& hit_point,
                        const Vec3& hit_normal, const Vec3& ray_direction) const {
    const LightRadiance le = light->radiance(hit_point, hit_normal, ray_direction);
    if (le.radiance.is_black()) return Rgb(0.0f);
    // Directly visible emitters: no other technique samples paths of length 1.
    if (state.path_length == 1) return le.radiance;
    // Without connections (LT, PPM, BPM), emission found by the eye counts only along purely
    // specular chains, which nothing else can sample; every other path is left to the light
    // subpaths (connections to the camera, or merging).
    if (!use_vc_) return state.specular_path ? le.radiance : Rgb(0.0f);
    const float pick_probability = scene_.emitter_pick_probability(light);
    // J1 at s = 1 of the eye vertex before the hit point (sampled toward it): it multiplies
    // next-event estimation's term.
    float joint_ratio = 0;
    if (joint_ && light->is_finite() && state.origin_joint_pdf > 0)
        joint_ratio =
            joint_pdf_l(state.origin_previous, state.origin, hit_point) / state.origin_joint_pdf;
    // (J2 of the vertex before the hit point, resampled on the light's ray, is in dVC:
    // next_vertex added it on arriving here.)
    return le.radiance * mis_.weight_emission(state.mis, le.pdf_direct_a * pick_probability,
                                              le.pdf_emission_w * pick_probability, joint_ratio);
}

Rgb Iteration::medium_emission(const SubpathState& state, const Vertex& v) const {
    const Light* light = scene_.volume_light_of(v.medium);
    if (!light) return Rgb(0.0f);
    const VolumeEmitter& emitter = *light->as_volume();
    const Rgb le = state.source_throughput * emitter.source_in_medium(v.p);
    if (le.is_black()) return Rgb(0.0f);
    // As emission(): directly visible emission has no other technique, and without
    // connections only purely specular chains count (light subpaths sample the rest).
    if (state.path_length == 1) return le;
    if (!use_vc_) return state.specular_path ? le : Rgb(0.0f);
    // Next-event estimation's density of this point (volume measure) and the light subpath's.
    const float direct_pdf_a = scene_.emitter_pick_probability(light) * emitter.pdf_volume(v.p);
    return le * volume_emission_weight(mis_, state.mis, direct_pdf_a);
}

Rgb Iteration::direct_illumination(const SubpathState& state, const SubpathVertex& v,
                                   const Vec3& wo, Rng& rng, RenderStats& stats) const {
    DirectLightSample dl;
    if (!sample_direct_emitter(scene_, v.p, rng, dl)) return Rgb(0.0f);
    return direct_contribution(state.mis, v, wo, dl, rng, stats);
}

Rgb Iteration::direct_contribution(const MisQuantities& eye_mis, const SubpathVertex& v,
                                   const Vec3& wo, const DirectLightSample& dl, Rng& rng,
                                   RenderStats& stats, bool joint) const {
    const LightIlluminateSample& ls = dl.ls;
    const auto [f, pdf_w] = v.evaluate(wo, ls.wi);
    if (f.is_black()) return Rgb(0.0f);
    const Ray ray = dl.shadow_ray(scene_, v.p, v.n);
    // A volume light's point is a medium vertex: the eye would reach it by a scattering event.
    const Link l = link(ray, v.medium_toward(wo, ls.wi), v.in_medium(),
                        dl.light->as_volume() != nullptr, rng, stats);
    if (l.traced && l.transmittance.is_black()) return Rgb(0.0f);
    // B-B1D at v, the light's emission segment toward v as the photon beam: the emission's
    // density of v (relative to the light's direct density, as eq. 45 forms it) with and
    // without the distance density.
    float eye_photon_beam = 0;
    if (v.photon_beam > 0 && ls.cos_at_light > 0) {
        const float emission =
            ls.pdf_emission_w * v.cos(ls.wi) / (ls.pdf_direct_w * ls.cos_at_light);
        eye_photon_beam = mis_.photon_beam_eye_term(length(cross(wo, ls.wi)), v.arrival_distance,
                                                    v.sigma_t, emission * l.densities.toward_start,
                                                    emission, beam_segment(l.densities));
    }
    // J1 at s = 1 (v sampled from its predecessor toward the light point).
    float joint_ratio = 0;
    if (joint_ && v.joint_distance_pdf > 0 && std::isfinite(ls.distance))
        joint_ratio =
            joint_pdf_l(v.previous, v.p, v.p + ls.wi * ls.distance) / v.joint_distance_pdf;
    // J2 of the junction toward the camera, v resampled on the ray from the light's point.
    const float eye_joint2 = std::isfinite(ls.distance)
                                 ? eye_joint2_toward(eye_mis, v, v.p + ls.wi * ls.distance, l)
                                 : 0.0f;
    // Eqs. (44) and (45); VPL rendering has no other technique for these paths.
    const DirectTechnique technique{.bsdf_forward_w = pdf_w.forward,
                                    .bsdf_reverse_w = pdf_w.reverse,
                                    .light_pdf_w = dl.pdf_w(),
                                    .emission_pdf_w = ls.pdf_emission_w,
                                    .direct_pdf_w = ls.pdf_direct_w,
                                    .cos_here = v.cos(ls.wi),
                                    .cos_light = ls.cos_at_light,
                                    .delta_light = dl.light->is_delta(),
                                    .eye_medium = v.in_medium(),
                                    .eye_query_beam = v.query_beam,
                                    .pass_to_light_probability = l.densities.toward_end,
                                    .distance_from_light = l.densities.toward_start,
                                    .eye_photon_beam = eye_photon_beam,
                                    .joint_ratio = joint_ratio,
                                    .eye_joint2 = eye_joint2};
    const float weight = many_lights_ ? 1.0f
                         : joint      ? mis_.weight_joint_direct(eye_mis, technique)
                                      : mis_.weight_direct(eye_mis, technique);
    const Rgb contribution = ls.radiance * f * (weight * v.shading_cos(ls.wi) / dl.pdf_w());
    if (contribution.is_black()) return Rgb(0.0f);
    return contribution * visibility(l, ray, stats);
}

std::optional<ConnectionGeometry> Iteration::connection_geometry(const LightVertex& lv,
                                                                 const Vertex& v, const Vec3& wo) {
    const Vertex& w = lv.vertex;
    Vec3 d = w.p - v.p;
    const float dist2 = length_squared(d);
    if (!(dist2 > 0)) return std::nullopt;
    d = d / std::sqrt(dist2);
    const BsdfEvaluation eye = v.evaluate(wo, d);
    if (eye.f.is_black()) return std::nullopt;
    const BsdfEvaluation light = w.evaluate(lv.wo, -d);
    if (light.f.is_black()) return std::nullopt;
    return ConnectionGeometry{d, dist2, eye, light};
}

std::optional<Iteration::ConnectionTerms> Iteration::connection_terms(
    const LightVertex& lv, const Joint2Vertex& w2, const SubpathVertex& v, const Vec3& wo,
    const MisQuantities& eye_mis, Rng& rng, RenderStats& stats, JointKind joint) const {
    const std::optional<ConnectionGeometry> g = connection_geometry(lv, v, wo);
    if (!g) return std::nullopt;
    const Vertex& w = lv.vertex;
    const Vec3& d = g->d;
    const float dist2 = g->dist2;
    const auto& [f_eye, eye_pdf_w] = g->eye;
    const auto& [f_light, light_pdf_w] = g->light;
    const Ray ray = scene_.spawn_ray_to(v.p, v.n, w.p, w.n);
    const Link l = link(ray, v.medium_toward(wo, d), v.in_medium(), w.in_medium(), rng, stats);
    if (l.traced && l.transmittance.is_black()) return std::nullopt;
    // Densities of extending either subpath to the other's endpoint (area, or volume in a
    // medium, with the distance sampling through media).
    const float eye_pdf_a = eye_pdf_w.forward * w.cos(d) * l.densities.toward_end / dist2;
    const float light_pdf_a = light_pdf_w.forward * v.cos(d) * l.densities.toward_start / dist2;
    // J1 techniques of this junction (the eye vertex sampled toward the light vertex) and of
    // the one before it (the light vertex sampled from the eye vertex toward its predecessor).
    float joint_ratio = 0, light_joint_ratio = 0;
    if (joint_) {
        if (v.joint_distance_pdf > 0)
            joint_ratio = joint_pdf_l(v.previous, v.p, w.p) / v.joint_distance_pdf;
        if (w.in_medium() && joint_light_side(lv.path_length, lv.finite_light) && l.one_piece &&
            l.densities.toward_end > 0)
            light_joint_ratio = joint_pdf_l(v.p, w.p, w.previous) / l.densities.toward_end;
    }
    // J2 of this junction (the light vertex resampled on the light ray that reached it) and of
    // the one before it (the light vertex's predecessor resampled there, the light vertex by J1).
    float joint2_ratio = 0, light_joint2 = 0;
    if (joint_ratio > 0)
        joint2_ratio = light_joint2_ratio(w.previous, w.p, w2.light_ray_pdf, v.previous, v.p);
    if (light_joint_ratio > 0)
        light_joint2 =
            light_joint2_ratio(w2.previous2, w.previous, w2.previous_light_ray_pdf, v.p, w.p);
    // J2 of the junction toward the camera: v resampled on the connection segment from w.
    const float eye_joint2 = eye_joint2_toward(eye_mis, v, w.p, l);
    // Eqs. (40) and (41).
    const ConnectionTechnique technique{
        .eye_pdf_a = eye_pdf_a,
        .light_pdf_a = light_pdf_a,
        .light_reverse_w = light_pdf_w.reverse,
        .eye_reverse_w = eye_pdf_w.reverse,
        .light_medium = w.in_medium(),
        .eye_medium = v.in_medium(),
        .eye_query_beam = v.query_beam,
        // P-B2D at the light vertex, the connection as the query.
        .light_query_beam =
            w.in_medium() ? mis_.query_beam_term(eye_pdf_w.forward * w.cos(d) / dist2) : 0.0f,
        .light_joint_ratio = light_joint_ratio,
        .joint_ratio = joint_ratio,
        .light_joint2_ratio = light_joint2,
        .joint2_ratio = joint2_ratio,
        .eye_joint2 = eye_joint2,
        // B-B1D at the light vertex (the connection as the query) and at the eye vertex (the
        // connection as the photon beam).
        .light_photon_beam =
            light_photon_beam_term(w, lv.wo, d, eye_pdf_w.forward * w.cos(d) / dist2),
        .eye_photon_beam =
            v.photon_beam > 0
                ? mis_.photon_beam_eye_term(length(cross(wo, d)), v.arrival_distance, v.sigma_t,
                                            light_pdf_a, light_pdf_w.forward * v.cos(d) / dist2,
                                            beam_segment(l.densities))
                : 0.0f};
    const float weight =
        joint == JointKind::J2   ? mis_.weight_joint2_connection(lv.mis, eye_mis, technique)
        : joint == JointKind::J1 ? mis_.weight_joint_connection(lv.mis, eye_mis, technique)
                                 : mis_.weight_connection(lv.mis, eye_mis, technique);
    const float geometry = v.shading_cos(d) * w.shading_cos(d) / dist2;
    const Rgb contribution = f_eye * f_light * (geometry * weight);
    if (contribution.is_black()) return std::nullopt;
    return ConnectionTerms{*g, contribution, ray, l};
}

Rgb Iteration::connect_vertices(const LightVertex& lv, const Joint2Vertex& light_joint2,
                                const SubpathVertex& v, const Vec3& wo,
                                const MisQuantities& eye_mis, Rng& rng, RenderStats& stats) const {
    const std::optional<ConnectionTerms> t =
        connection_terms(lv, light_joint2, v, wo, eye_mis, rng, stats);
    if (!t) return Rgb(0.0f);
    return t->unoccluded * visibility(t->link, t->ray, stats);
}

void Iteration::add_arrival_joint2_term(MisQuantities& mis, const SubpathState& state,
                                        const Vec3& x, float cos_in, float distance_pdf) const {
    if (!joint2_ || !(state.carried_eye_joint2 > 0) || !state.origin_in_medium || !state.medium ||
        !state.medium->is_homogeneous())
        return;
    mis_.add_eye_joint2_term(mis, state.carried_eye_joint2,
                             joint2_pdf_l(scene_.bounding_sphere(), x, state.origin,
                                          state.origin_previous2, state.origin_previous),
                             cos_in, distance_pdf);
}

float Iteration::eye_joint2_toward(const MisQuantities& eye_mis, const SubpathVertex& v,
                                   const Vec3& y, const Link& link) const {
    if (!joint2_ || !(v.camera_joint_ratio > 0) || !v.in_medium() || !v.medium->is_homogeneous() ||
        !link.one_piece || !(link.densities.toward_start > 0))
        return 0.0f;
    return mis_.eye_joint2_term(
        eye_mis, v.camera_joint_ratio,
        joint2_pdf_l(scene_.bounding_sphere(), y, v.p, v.joint2.previous2, v.previous) /
            link.densities.toward_start);
}

void Iteration::include_joint_junction(MisQuantities& mis, const SubpathState& state,
                                       SubpathVertex& v) const {
    // The junction's eye-side vertex is the one the eye came from (a medium vertex reached in
    // one piece, else it has no J1 technique), sampled toward v.
    if (!joint_ || !(state.origin_joint_pdf > 0)) return;
    v.camera_joint_ratio =
        joint_pdf_l(state.origin_previous, state.origin, v.p) / state.origin_joint_pdf;
    mis_.include_joint_junction(mis, v.camera_joint_ratio);
}

template <class Add>
void Iteration::joint_connections(const Ray& ray, const SubpathState& state, uint32_t first,
                                  uint32_t end, uint32_t rays_first, uint32_t rays_end, Rng& rng,
                                  RenderStats& stats, Add&& add) const {
    const Medium* medium = state.medium;
    // J1 at s = 1 is next-event estimation's sibling: there whenever next-event estimation is.
    const bool toward_light = 1 + state.path_length <= max_length_;
    if (!medium || (first == end && !toward_light)) return;
    // The segment's first piece ends at the first surface, null or not: J1 samples past it
    // contribute nothing (the technique's density is over the whole half-line, so that every
    // other technique can evaluate it without tracing).
    ++stats.rays;
    const float first_piece = scene_.closest_hit_distance(ray);
    const Vec3 wo = -ray.direction;
    // A medium vertex of the first piece sampled toward `target`: the eye throughput there
    // (transmittance times sigma_s over J1's density), the vertex and the eye subpath's MIS
    // quantities as distance sampling would have produced them (against which J1's weight is
    // taken); nullopt if the sample lies past the first piece or carries nothing.
    struct JointVertex {
        Rgb eye_weight;
        SubpathVertex v;
        MisQuantities mis;
    };
    auto sample_vertex = [&](const Vec3& target) -> std::optional<JointVertex> {
        const HalfLineEquiAngularSampler sampler(state.origin, ray.direction, target);
        const float t = sampler.sample(rng.next_1d());
        const float pdf = sampler.pdf_l(t);
        const Vec3 z = state.origin + ray.direction * t;
        const float t_ray = dot(z - ray.origin, ray.direction);
        if (!(t_ray > 0 && t_ray < first_piece && pdf > 0)) return std::nullopt;
        const Rgb sigma_s = medium->sigma_s(z);
        if (sigma_s.is_black()) return std::nullopt;
        JointVertex j;
        j.eye_weight =
            state.throughput * medium->transmittance(ray, t_ray, rng) * sigma_s * (1.0f / pdf);
        if (j.eye_weight.is_black() || !j.eye_weight.is_finite()) return std::nullopt;
        SegmentDensityBuilder builder(state.in_medium);
        builder.add_piece(medium, ray, t_ray);
        const SegmentDensities densities = builder.finish(true);
        j.v.p = z;
        j.v.medium = medium;
        j.v.phase = &medium->phase();
        j.v.previous = state.origin;
        j.v.joint2.previous2 = state.origin_previous;
        j.v.joint2.previous_light_ray_pdf = state.origin_light_ray_pdf;
        j.v.joint_distance_pdf = densities.toward_end;
        j.mis = state.mis;
        mis_.arrive(j.mis, t_ray * t_ray, true, 1.0f, densities.toward_end, densities.toward_start);
        // As next_vertex (the first piece is one piece).
        add_arrival_joint2_term(j.mis, state, z, 1.0f, densities.toward_end);
        include_joint_junction(j.mis, state, j.v);
        return j;
    };
    if (toward_light) {
        // J1 at s = 1: a light and a point on it drawn as next-event estimation draws them (the
        // point depends on the numbers alone, Light::sample_position), then the medium vertex
        // sampled toward that point and connected to it with the same numbers.
        DirectLightSample dl;
        dl.light = scene_.sample_light(rng.next_1d(), &dl.pick_probability);
        const Vec2 u = rng.next_2d();
        Vec3 light_point;
        if (dl.light && dl.pick_probability > 0 && dl.light->sample_position(u, light_point)) {
            if (const std::optional<JointVertex> j = sample_vertex(light_point);
                j && dl.light->illuminate(j->v.p, u, dl.ls) && dl.ls.pdf_direct_w > 0)
                add(1, j->eye_weight *
                           direct_contribution(j->mis, j->v, wo, dl, rng, stats, /*joint=*/true));
        }
    }
    // J2: the vertex at the end of each of the pixel's light path's rays (its emission ray and
    // the rays its vertices scattered into, in homogeneous media) resampled on it by B2, then
    // the eye vertex toward it by J1.
    for (uint32_t r = rays_first; r < rays_end; ++r) {
        const LightRay& light_ray = light_rays_[r];
        if (light_ray.path_length + 1 + state.path_length > max_length_) break;
        Joint2Vertex b_joint2;
        if (const std::optional<LightVertex> b =
                resample_on_light_ray(light_ray, state.origin, ray.direction, b_joint2, rng)) {
            if (const std::optional<JointVertex> j = sample_vertex(b->vertex.p)) {
                if (const std::optional<ConnectionTerms> c =
                        connection_terms(*b, b_joint2, j->v, wo, j->mis, rng, stats, JointKind::J2))
                    add(b->path_length + 1, j->eye_weight * b->throughput * c->unoccluded *
                                                visibility(c->link, c->ray, stats));
            }
        }
    }
    for (uint32_t i = first; i < end; ++i) {
        const LightVertex& lv = light_vertices_[i];
        if (lv.path_length + 1 + state.path_length > max_length_) break;
        const std::optional<JointVertex> j = sample_vertex(lv.vertex.p);
        if (!j) continue;
        const std::optional<ConnectionTerms> c =
            connection_terms(lv, joint2_of(i), j->v, wo, j->mis, rng, stats, JointKind::J1);
        if (!c) continue;
        add(lv.path_length + 1,
            j->eye_weight * lv.throughput * c->unoccluded * visibility(c->link, c->ray, stats));
    }
}

std::optional<LightVertex> Iteration::resample_on_light_ray(const LightRay& e,
                                                            const Vec3& eye_origin,
                                                            const Vec3& eye_direction,
                                                            Joint2Vertex& joint2, Rng& rng) const {
    const float range = light_ray_range(scene_.bounding_sphere(), e.origin, e.direction);
    if (!(range > 0)) return std::nullopt;
    const JointLightDistanceSampler b2(e.origin, e.direction, eye_origin, eye_direction, range);
    const float t = b2.sample(rng.next_1d());
    const float pdf = b2.pdf_l(t);
    // Samples past the ray's first piece contribute nothing (B2's density covers the whole
    // range so that every technique evaluates the same density without tracing).
    if (!(pdf > 0 && t > 0 && t < e.piece_end)) return std::nullopt;
    const Medium* medium = e.medium;
    const Ray ray(e.origin, e.direction);
    const Vec3 b = ray.at(t);
    const Rgb sigma_s = medium->sigma_s(b);
    if (sigma_s.is_black()) return std::nullopt;
    // The vertex as if distance sampling had reached it (next_vertex), with B2's density.
    SegmentDensityBuilder builder(e.origin_in_medium);
    builder.add_piece(medium, ray, t);
    const SegmentDensities densities = builder.finish(true);
    LightVertex lv{};
    lv.vertex.p = b;
    lv.vertex.medium = medium;
    lv.vertex.phase = &medium->phase();
    lv.vertex.previous = e.origin;
    lv.vertex.joint_distance_pdf = densities.toward_end;
    joint2 = Joint2Vertex{};
    joint2.previous2 = e.origin_previous;
    joint2.light_ray_pdf = densities.toward_end;
    joint2.previous_light_ray_pdf = e.origin_light_ray_pdf;
    lv.wo = -e.direction;
    lv.throughput = e.throughput * medium->transmittance(ray, t, rng) * sigma_s * (1.0f / pdf);
    if (!lv.throughput.is_finite() || lv.throughput.is_black()) return std::nullopt;
    lv.path_length = e.path_length;
    lv.finite_light = e.finite_light;
    lv.mis = e.mis;
    mis_.arrive(lv.mis, t * t, e.path_length > 1 || e.finite_light, 1.0f, densities.toward_end,
                densities.toward_start);
    // J1's deferred term of the junction whose eye-side vertex is the ray's origin (next_vertex).
    if (e.carried_connection > 0 && e.origin_in_medium &&
        joint_light_side(e.path_length - 1, e.finite_light))
        mis_.add_joint_term(lv.mis, e.carried_connection,
                            joint_pdf_l(b, e.origin, e.origin_previous), 1.0f, densities.toward_end,
                            light_joint2_ratio(e.origin_previous2, e.origin_previous,
                                               e.origin_previous_light_ray_pdf, b, e.origin));
    return lv;
}

template <class Term, class Add>
void Iteration::draw_from_importance_caches(const Vertex& v, int eye_length, Rng& rng, Term&& term,
                                            Add&& add) const {
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
            if (!(factor > 0) || lv.path_length + 1 + eye_length > max_length_) continue;
            add(lv.path_length + 1, term(lv) * float(factor));
        }
    }
}

float Iteration::merge_joint_ratio(const LightVertex& lv, const Vertex& v) const {
    if (!joint_ || !(v.joint_distance_pdf > 0) ||
        !joint_light_side(lv.path_length, lv.finite_light))
        return 0.0f;
    return joint_pdf_l(v.previous, v.p, lv.vertex.previous) / v.joint_distance_pdf;
}

Rgb Iteration::merge(const Vertex& v, const Vec3& wo, const SubpathState& state) const {
    const bool medium = v.in_medium();
    const HashGrid& grid = medium ? medium_grid_ : surface_grid_;
    Rgb sum(0.0f);
    // What a merge reads of a light vertex is its first cache line (LightVertex), and its last
    // where J1 (vertex.previous) or photon beams (vertex.photon_beam) take part in the weight.
    const bool last_line = (joint_ && v.joint_distance_pdf > 0) || v.photon_beam > 0;
    auto prefetch = [&](uint32_t i) {
        const LightVertex& lv = light_vertices_[i];
        __builtin_prefetch(&lv);
        if (last_line) __builtin_prefetch(&lv.finite_light);
    };
    grid.for_each_within_radius(v.p, prefetch, [&](uint32_t i) {
        const LightVertex& lv = light_vertices_[i];
        if (lv.path_length + state.path_length > max_length_) return;
        // The photon arrived from lv.wo; the eye vertex scatters it toward wo.
        const auto [f, pdf_w] = v.evaluate(wo, lv.wo);
        if (f.is_black()) return;
        float weight = 1.0f;
        if (!ppm_) {
            // Eqs. (38) and (39).
            weight = mis_.weight_merge(
                lv.mis, state.mis,
                {.eye_forward_w = pdf_w.forward,
                 .eye_reverse_w = pdf_w.reverse,
                 .medium = medium,
                 .query_beam = v.query_beam,
                 .photon_beam = v.photon_beam > 0 && lv.vertex.photon_beam > 0
                                    ? mis_.photon_beam_merge_term(length(cross(wo, lv.wo)),
                                                                  lv.vertex.arrival_distance,
                                                                  v.arrival_distance, v.sigma_t)
                                    : 0.0f,
                 .light_joint_ratio = merge_joint_ratio(lv, v)});
        }
        Rgb photon = lv.throughput;
        if (medium) {
            // Both subpaths' throughputs carry sigma_s at their medium vertex (the distance
            // sampling weight); the merged path scatters once, so one of them is divided out.
            const Rgb sigma_s = lv.vertex.medium->sigma_s(lv.vertex.p);
            for (int c = 0; c < 3; ++c) photon[c] = sigma_s[c] > 0 ? photon[c] / sigma_s[c] : 0.0f;
        }
        sum += f * photon * weight;
    });
    return sum * (medium ? vm_normalization_volume_ : vm_normalization_);
}

Rgb Iteration::trace_eye_path(uint64_t pixel, RenderStats& stats, const LayerSink& sink) const {
    Rng rng(StreamKey{key_.seed, key_.frame, key_.iteration, pixel});
    const int width = camera_.width();
    const Vec2 jitter = rng.next_2d();
    Ray ray = camera_.generate_ray(
        Vec2(float(pixel % width) + jitter.x, float(pixel / width) + jitter.y));
    SubpathState state;
    state.throughput = Rgb(1.0f);
    state.initial_luminance = 1.0f;
    state.mis = mis_.start_camera(camera_pixel_pdf_w(ray.direction));
    state.medium = scene_.camera_medium();
    state.origin = ray.origin;

    Rgb color(0.0f);
    // s light vertices and t = path_length + 1 eye vertices (the camera included).
    auto add = [&](Technique kind, int s, const Rgb& contribution) {
        color += contribution;
        sink.add(kind, s, state.path_length + 1, contribution);
    };
    // The pixel's light path (connections and joint connections).
    uint32_t light_first = 0, light_end = 0;
    uint32_t rays_first = 0, rays_end = 0;  // its J2 light rays
    if (use_vc_ && !ic_connections_ && !path_ends_.empty()) {
        const uint64_t path = pixel % light_path_count_;
        light_first = path == 0 ? 0 : path_ends_[path - 1];
        light_end = path_ends_[path];
        if (path < ray_ends_.size()) {
            rays_first = path == 0 ? 0 : ray_ends_[path - 1];
            rays_end = ray_ends_[path];
        }
    }
    for (;; ++state.path_length) {
        if (joint_ && state.path_length < max_length_)
            joint_connections(ray, state, light_first, light_end, rays_first, rays_end, rng, stats,
                              [&](int s, const Rgb& c) { add(Technique::Connection, s, c); });
        if (query_beams_ && photon_beams_ && state.path_length < max_length_) {
            Rgb query_sum, photon_sum;
            both_beams(ray, state, rng, stats, query_sum, photon_sum);
            add(Technique::Merging, 0, state.throughput * query_sum);
            add(Technique::Merging, 0, state.throughput * photon_sum);
        } else if (query_beams_ && state.path_length < max_length_) {
            add(Technique::Merging, 0, state.throughput * query_beams(ray, state, rng, stats));
        } else if (photon_beams_ && state.path_length < max_length_) {
            add(Technique::Merging, 0, state.throughput * photon_beams(ray, state, rng, stats));
        }
        SampledSegment seg;
        std::optional<SubpathVertex> v =
            next_vertex(ray, TransportMode::Radiance, rng, state, stats, seg);
        if (!v) {
            if (seg.end == SegmentEnd::Escaped && !state.throughput.is_black()) {
                // Left the scene: the distance sampling on the way is part of this
                // technique's density; an infinite light has no distance or cosine term.
                mis_.arrive(state.mis, 0.0f, false, 1.0f, seg.densities.toward_end,
                            seg.densities.toward_start);
                mis_.add_photon_beam_term(state.mis, state.carried_photon_beam, 1.0f,
                                          seg.densities.toward_end, seg.densities.toward_start,
                                          true, beam_segment(seg.densities));
                for (const Light* light : scene_.background_lights())
                    add(Technique::Connection, 0,
                        state.throughput * emission(light, state, Vec3(), Vec3(), ray.direction));
            }
            break;
        }
        const Vec3 wo = -ray.direction;
        if (!v->in_medium() && seg.si.emitter)
            add(Technique::Connection, 0,
                state.throughput * emission(seg.si.emitter, state, v->p, v->n, ray.direction));
        if (v->in_medium() && v->medium->is_emissive() && !scene_.volume_lights().empty()) {
            add(Technique::Connection, 0, medium_emission(state, *v));
            if (state.throughput.is_black()) break;  // nothing scatters here (albedo 0)
        }
        if (state.path_length >= max_length_) break;
        // Every technique below treats v as a scattering vertex (emission above: as the light).
        include_joint_junction(state.mis, state, *v);

        // Light tracing and PPM leave every non-delta scattering of the eye path to the light
        // paths (camera connections or the one merge); the eye continues only through delta
        // lobes, including the delta lobes of mixed materials such as plastic's coating.
        const bool eye_ends_at_non_delta = light_trace_only_ || ppm_ || many_lights_;
        if (v->has_non_delta() && !light_trace_only_) {
            if (many_lights_) {
                add(Technique::Connection, 1,
                    state.throughput * direct_illumination(state, *v, wo, rng, stats));
            }
            if (ic_) {
                draw_from_importance_caches(
                    *v, state.path_length, rng,
                    [&](const LightVertex& lv) {
                        return lv.throughput * vpl_connection(lv, *v, wo, vpl_clamp2_, rng, stats);
                    },
                    [&](int s, const Rgb& c) {
                        add(Technique::Connection, s, state.throughput * c);
                    });
            }
            if (vpl_) {
                for (const LightVertex& lv : light_vertices_) {
                    if (lv.path_length + 1 + state.path_length > max_length_) continue;
                    add(Technique::Connection, lv.path_length + 1,
                        state.throughput * lv.throughput *
                            vpl_connection(lv, *v, wo, vpl_clamp2_, rng, stats));
                }
            }
            if (use_vc_) {
                add(Technique::Connection, 1,
                    state.throughput * direct_illumination(state, *v, wo, rng, stats));
            }
            if (ic_connections_) {
                // (1 / N) sum over the N cached light paths of their connections to v: its
                // expectation is one light path's, so every MIS weight stays as it is.
                draw_from_importance_caches(
                    *v, state.path_length, rng,
                    [&](const LightVertex& lv) {
                        // No J2 beside ic connections (joint_ is off there).
                        return lv.throughput *
                               connect_vertices(lv, Joint2Vertex{}, *v, wo, state.mis, rng, stats) *
                               ic_connection_scale_;
                    },
                    [&](int s, const Rgb& c) {
                        add(Technique::Connection, s, state.throughput * c);
                    });
            } else if (use_vc_) {
                for (uint32_t i = light_first; i < light_end; ++i) {
                    const LightVertex& lv = light_vertices_[i];
                    if (lv.path_length + 1 + state.path_length > max_length_) break;
                    add(Technique::Connection, lv.path_length + 1,
                        state.throughput * lv.throughput *
                            connect_vertices(lv, joint2_of(i), *v, wo, state.mis, rng, stats));
                }
            }
            if (v->in_medium() ? merge_points_ : merge_surfaces_) {
                add(Technique::Merging, 0, state.throughput * merge(*v, wo, state));
            }
        }
        if (eye_ends_at_non_delta && !v->has_delta()) break;
        if (!sample_scattering(*v, wo, rng, state, ray)) break;
        if (eye_ends_at_non_delta && !state.specular_path) break;
    }
    return color;
}

}  // namespace vcm_detail

using vcm_detail::Iteration;
using vcm_detail::IterationStorage;
using vcm_detail::Splat;

VertexConnectionMerging::VertexConnectionMerging(const BidirectionalConfig& config)

    : config_(config), storage_(std::make_unique<IterationStorage>()) {}

VertexConnectionMerging::~VertexConnectionMerging() = default;

void VertexConnectionMerging::render_iteration(const Scene& scene, const IterationKey& key,

                                               AccumulationBuffer& target, TechniqueLayers* layers,

                                               RenderStats& stats) const {
    std::lock_guard lock(storage_mutex_);

    Iteration iteration(config_, scene, key, *storage_);

    if (!scene.lights().empty() || !scene.volume_lights().empty()) {
        // The light tracer's splats reach the image in chunk order and before the eye pass's

        // estimates, so that each pixel's sum is the same whatever the number of threads.

        iteration.trace_light_paths(stats, [&](std::span<const Splat> splats) {
            for (const Splat& splat : splats) {
                if (!splat.value.is_finite()) {
                    ++stats.non_finite;

                    continue;
                }

                target.add(splat.pixel, splat.value);

                if (layers)

                    layers->add(layers->index(Technique::Connection, splat.light_vertices, 1),

                                splat.pixel, splat.value);
            }
        });

        if (config_.mode == BidirectionalMode::Vpl && config_.vpl_importance)

            iteration.select_vpls(stats);

        if (iteration.uses_importance_caches()) iteration.build_importance_cache(stats);
    }

    const int width = scene.camera().width(), height = scene.camera().height();

    for_each_pixel(width, height, target, stats, [&](uint64_t pixel, RenderStats& local) {
        return iteration.trace_eye_path(pixel, local, LayerSink{layers, pixel});
    });
}

VplSelection VertexConnectionMerging::inspect_vpl_selection(const Scene& scene,

                                                            const IterationKey& key) const {
    VplSelection selection;

    if (config_.mode != BidirectionalMode::Vpl || !config_.vpl_importance || scene.lights().empty())

        return selection;

    IterationStorage storage;

    Iteration iteration(config_, scene, key, storage);

    RenderStats stats;

    iteration.trace_light_paths(stats, [](std::span<const Splat>) {});

    iteration.select_vpls(stats, &selection);

    selection.light_paths = iteration.light_path_count();

    selection.importance_records = config_.importance_records;

    selection.record_distance_clamp = std::sqrt(double(iteration.record_clamp2()));

    return selection;
}

PhotonBeamInspection VertexConnectionMerging::inspect_photon_beams(const Scene& scene,

                                                                   const IterationKey& key) const {
    PhotonBeamInspection out;

    if (config_.mode != BidirectionalMode::Vcm || !config_.photon_beams ||

        (scene.lights().empty() && scene.volume_lights().empty()))

        return out;

    IterationStorage storage;

    Iteration iteration(config_, scene, key, storage);

    RenderStats stats;

    iteration.trace_light_paths(stats, [](std::span<const Splat>) {});

    out.lines = storage.photon_beam_lines;

    out.radius = iteration.photon_beam_radius();

    return out;
}

}  // namespace render
