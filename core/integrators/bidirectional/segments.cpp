// One subpath step, shared by every pass: the next vertex, a connection's link through media
// and its visibility, and the scattering that starts the next segment.
#include "core/integrators/bidirectional/iteration.h"

namespace render::bidirectional {

// --- segments and links -----------------------------------------------------------------------

std::optional<SubpathVertex> Iteration::next_vertex(const Ray& ray, TransportMode mode, Rng& rng,
                                                    SubpathState& state, RenderStats& stats,
                                                    SampledSegment& seg,
                                                    const TracedPieces* traced) const {
    if (!state.medium && !scene_.has_media()) {
        // Surface-only scenes: one closest hit, every distance density 1 (as sample_segment
        // would return, without its bookkeeping).
        ++stats.rays;
        if (!scene_.intersect(ray, seg.si)) return std::nullopt;
        seg.end = SegmentEnd::Surface;
        seg.position = seg.si.p;
        seg.distance = seg.si.t;
    } else {
        seg = sample_segment(scene_, ray, state.medium, state.in_medium, rng, stats, traced);
        if (plan_.camera_medium_rule && arrives_against_declaration(seg, ray)) {
            // The region just crossed is in another medium for camera paths than this subpath
            // gave it (docs/design/media.md, "Which medium a path is in"). A light subpath's
            // sample of it counts for no path: it stops. An eye subpath drops the techniques
            // whose light subpath would have crossed it (those before this vertex); the
            // technique whose light subpath starts at this vertex keeps its term (dVCM).
            if (mode == TransportMode::Importance) return std::nullopt;
            state.mis.dVC = 0;
            state.mis.dVM = 0;
        }
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
        if (plan_.joint2 && mode == TransportMode::Importance && seg.one_piece &&
            joint_light_side(state.path_length, state.is_finite_light) &&
            seg.medium->is_homogeneous())
            v.joint2.light_ray_pdf = seg.densities.toward_end;
        if (mode == TransportMode::Radiance)
            v.query_beam = mis_.query_beam_factor(seg.densities.toward_end);
        if (plan_.photon_beams) set_photon_beam_quantities(v, seg, mode);
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
    if (plan_.joint && mode == TransportMode::Importance && state.carried_connection > 0 &&
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

bool Iteration::arrives_against_declaration(const SampledSegment& seg, const Ray& ray) {
    return seg.against_declaration ||
           (seg.end == SegmentEnd::Surface &&
            render::arrives_against_declaration(*seg.si.shape, seg.si.geometric_normal,
                                                ray.direction, seg.medium));
}

Link Iteration::link(const Ray& ray, const Medium* medium, bool start_in_medium, bool end_in_medium,
                     Rng& rng, RenderStats& stats) const {
    if (!scene_.has_media()) return Link{};
    const SegmentConnection c =
        connect_segment(scene_, ray, medium, start_in_medium, end_in_medium, rng, stats);
    return Link{c.densities, c.transmittance,       true,
                c.one_piece, c.against_declaration, c.end_medium};
}

Rgb Iteration::visibility(const Link& l, const Ray& ray, RenderStats& stats) const {
    if (l.traced) return l.transmittance;
    ++stats.rays;
    return scene_.occluded(ray) ? Rgb(0.0f) : Rgb(1.0f);
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
    if (plan_.joint)
        state.carried_connection =
            mis_.carried_connection_term(state.mis, cos_out, bs->pdf_w.forward, bs->delta);
    // Eye subpaths (J2): the J1 share of the term this scatter adds, completed at the next
    // arrival (add_arrival_joint2_term; light subpaths ignore it).
    state.carried_eye_joint2 =
        plan_.joint2 && v.in_medium() && v.medium->is_homogeneous()
            ? mis_.carried_eye_joint2_term(state.mis, v.camera_joint_ratio, cos_out,
                                           bs->pdf_w.forward, bs->delta)
            : 0.0f;
    state.carried_query_beam =
        v.in_medium() ? mis_.carried_query_beam_term(cos_out, bs->pdf_w.forward, bs->delta) : 0.0f;
    if (plan_.photon_beams)
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

    if (plan_.roulette == RoulettePolicy::Albedo) {
        if (!survives_albedo_roulette(bs->weight, state.throughput, rng)) return false;
    } else if (state.path_length >= plan_.rr_depth) {
        const float q = std::min(0.95f, state.throughput.max() / state.initial_luminance);
        if (!(q > 0) || rng.next_1d() >= q) return false;
        state.throughput *= 1.0f / q;
    }
    state.medium = v.medium_toward(bs->wi);
    state.in_medium = v.in_medium();
    ray = v.in_medium() ? Ray(v.p, bs->wi) : scene_.spawn_ray(v.p, v.n, bs->wi);
    return true;
}

}  // namespace render::bidirectional
