// Connections: emission found by the eye (s = 0), next-event estimation (s = 1) and the
// connection of an eye vertex to a stored light vertex (s > 1), each MIS-weighted (vcm_mis.h).
#include "core/integrators/bidirectional/iteration.h"

namespace render::bidirectional {

// --- eye subpaths -----------------------------------------------------------------------------

Rgb Iteration::emission(const Light* light, const SubpathState& state, const LightRadiance& le,
                        const Vec3& hit_point, const Medium* arrival_medium) const {
    if (le.radiance.is_black()) return Rgb(0.0f);
    // Directly visible emitters: no other technique samples paths of length 1.
    if (state.path_length == 1) return le.radiance;
    // Without connections (LT, PPM, BPM), emission found by the eye counts only along purely
    // specular chains, which nothing else can sample; every other path is left to the light
    // subpaths (connections to the camera, or merging).
    if (!plan_.vertex_connections) return state.specular_path ? le.radiance : Rgb(0.0f);
    const float pick_probability = scene_.emitter_pick_probability(light);
    // Light subpaths from this light start in light_start_medium: where the eye arrives in
    // another, the light subpaths that reach here (s > 1) crossed a region in a medium camera
    // paths do not give it, and cannot sample this path (docs/design/media.md).
    const bool light_subpaths_sample =
        !plan_.camera_medium_rule || arrival_medium == light_start_medium(*light);
    // J1 at s = 1 of the eye vertex before the hit point (sampled toward it): it multiplies
    // next-event estimation's term.
    float joint_ratio = 0;
    if (plan_.joint && light->is_finite() && state.origin_joint_pdf > 0)
        joint_ratio =
            joint_pdf_l(state.origin_previous, state.origin, hit_point) / state.origin_joint_pdf;
    // (J2 of the vertex before the hit point, resampled on the light's ray, is in dVC:
    // next_vertex added it on arriving here.)
    return le.radiance *
           mis_.weight_emission(state.mis, le.pdf_direct_a * pick_probability,
                                light_subpaths_sample ? le.pdf_emission_w * pick_probability : 0.0f,
                                joint_ratio);
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
    if (!plan_.vertex_connections) return state.specular_path ? le : Rgb(0.0f);
    // Next-event estimation's density of this point (volume measure) and the light subpath's.
    const float direct_pdf_a = scene_.emitter_pick_probability(light) * emitter.pdf_volume(v.p);
    return le * volume_emission_weight(mis_, state.mis, direct_pdf_a);
}

Rgb Iteration::direct_illumination(const SubpathState& state, const SubpathVertex& v,
                                   const Vec3& wo, Rng& rng, RenderStats& stats) const {
    DirectLightSample dl;
    const auto medium_toward = [&v](const Vec3& wi) { return v.medium_toward(wi); };
    if (!sample_direct_emitter(scene_, v.p, medium_toward, rng, dl)) return Rgb(0.0f);
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
    const Link l = link(ray, v.medium_toward(ls.wi), v.in_medium(),
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
    if (plan_.joint && v.joint_distance_pdf > 0 && std::isfinite(ls.distance))
        joint_ratio =
            joint_pdf_l(v.previous, v.p, v.p + ls.wi * ls.distance) / v.joint_distance_pdf;
    // J2 of the junction toward the camera, v resampled on the ray from the light's point.
    const float eye_joint2 = std::isfinite(ls.distance)
                                 ? eye_joint2_toward(eye_mis, v, v.p + ls.wi * ls.distance, l)
                                 : 0.0f;
    // Eqs. (44) and (45); VPL rendering has no other technique for these paths.
    DirectTechnique technique{.bsdf_forward_w = pdf_w.forward,
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
    // The techniques whose light subpath covers v (the eye's share, w_camera) cross this shadow
    // ray: they cannot sample the path where it reaches a boundary against its declaration or
    // arrives in another medium than light subpaths start in (docs/design/media.md). A volume
    // light's point emits only where the ray arrives in its medium (source_seen_from).
    if (plan_.camera_medium_rule &&
        (l.against_declaration ||
         (!dl.light->as_volume() && l.end_medium != light_start_medium(*dl.light)))) {
        technique.emission_pdf_w = 0;
        technique.eye_photon_beam = 0;
    }
    const float weight = plan_.many_lights() ? 1.0f
                         : joint             ? mis_.weight_joint_direct(eye_mis, technique)
                                             : mis_.weight_direct(eye_mis, technique);
    const Rgb contribution = ls.radiance * f * (weight * v.shading_cos(ls.wi) / dl.pdf_w());
    if (contribution.is_black()) return Rgb(0.0f);
    return contribution * visibility(l, ray, stats);
}

std::optional<ConnectionGeometry> Iteration::connection_geometry(const LightVertex& lv,
                                                                 const Vertex& v, const Vec3& wo) {
    const LightVertex& w = lv;
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
    const MisQuantities& eye_mis, Rng& rng, RenderStats& stats, JointKind joint,
    const LightVertexMedia& light_media) const {
    const std::optional<ConnectionGeometry> g = connection_geometry(lv, v, wo);
    if (!g) return std::nullopt;
    const LightVertex& w = lv;
    const Vec3& d = g->d;
    const float dist2 = g->dist2;
    const auto& [f_eye, eye_pdf_w] = g->eye;
    const auto& [f_light, light_pdf_w] = g->light;
    const Ray ray = scene_.spawn_ray_to(v.p, v.n, w.p, w.n());
    const Link l = link(ray, v.medium_toward(d), v.in_medium(), w.in_medium(), rng, stats);
    if (l.traced && l.transmittance.is_black()) return std::nullopt;
    // Where the light subpath's last region goes on through w, the eye must reach w in the
    // medium the light subpath gave it; else no full path has these media (docs/design/media.md).
    // (The rule is on only where the caller passes the light vertex's media: eye_pass.cpp.)
    const bool w_keeps_medium =
        w.in_medium() || (light_media.shape && !is_medium_transition(*light_media.shape));
    if (plan_.camera_medium_rule && w_keeps_medium && l.end_medium != light_media.arrival)
        return std::nullopt;
    // Densities of extending either subpath to the other's endpoint (area, or volume in a
    // medium, with the distance sampling through media).
    const float eye_pdf_a = eye_pdf_w.forward * w.cos(d) * l.densities.toward_end / dist2;
    const float light_pdf_a = light_pdf_w.forward * v.cos(d) * l.densities.toward_start / dist2;
    // J1 techniques of this junction (the eye vertex sampled toward the light vertex) and of
    // the one before it (the light vertex sampled from the eye vertex toward its predecessor).
    float joint_ratio = 0, light_joint_ratio = 0;
    if (plan_.joint) {
        if (v.joint_distance_pdf > 0)
            joint_ratio = joint_pdf_l(v.previous, v.p, w.p) / v.joint_distance_pdf;
        if (w.in_medium() && joint_light_side(lv.path_length, lv.finite_light) && l.one_piece &&
            l.densities.toward_end > 0)
            light_joint_ratio = joint_pdf_l(v.p, w.p, w.previous()) / l.densities.toward_end;
    }
    // J2 of this junction (the light vertex resampled on the light ray that reached it) and of
    // the one before it (the light vertex's predecessor resampled there, the light vertex by J1).
    float joint2_ratio = 0, light_joint2 = 0;
    if (joint_ratio > 0)
        joint2_ratio = light_joint2_ratio(w.previous(), w.p, w2.light_ray_pdf, v.previous, v.p);
    if (light_joint_ratio > 0)
        light_joint2 =
            light_joint2_ratio(w2.previous2, w.previous(), w2.previous_light_ray_pdf, v.p, w.p);
    // J2 of the junction toward the camera: v resampled on the connection segment from w.
    const float eye_joint2 = eye_joint2_toward(eye_mis, v, w.p, l);
    // Eqs. (40) and (41).
    ConnectionTechnique technique{
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
    // The techniques whose light subpath covers v (w_camera) cross the connection: none
    // samples the path where it reaches a boundary against its declaration, on the way or at w.
    if (plan_.camera_medium_rule &&
        (l.against_declaration ||
         (!w_keeps_medium &&
          render::arrives_against_declaration(*light_media.shape, w.n(), d, l.end_medium)))) {
        technique.light_pdf_a = 0;
        technique.eye_photon_beam = 0;
    }
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
                                const MisQuantities& eye_mis, Rng& rng, RenderStats& stats,
                                const LightVertexMedia& light_media) const {
    const std::optional<ConnectionTerms> t = connection_terms(lv, light_joint2, v, wo, eye_mis, rng,
                                                              stats, JointKind::None, light_media);
    if (!t) return Rgb(0.0f);
    return t->unoccluded * visibility(t->link, t->ray, stats);
}

}  // namespace render::bidirectional
