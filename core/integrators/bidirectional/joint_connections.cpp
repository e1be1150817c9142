// Joint connections in homogeneous media (docs/design/media.md): J1, an eye segment's medium vertex
// sampled toward a light vertex, and J2, the light vertex resampled on its light ray as well.
#include "core/integrators/bidirectional/iteration.h"

namespace render::bidirectional {

void Iteration::add_arrival_joint2_term(MisQuantities& mis, const SubpathState& state,
                                        const Vec3& x, float cos_in, float distance_pdf) const {
    if (!plan_.joint2 || !(state.carried_eye_joint2 > 0) || !state.origin_in_medium ||
        !state.medium || !state.medium->is_homogeneous())
        return;
    mis_.add_eye_joint2_term(mis, state.carried_eye_joint2,
                             joint2_pdf_l(scene_.bounding_sphere(), x, state.origin,
                                          state.origin_previous2, state.origin_previous),
                             cos_in, distance_pdf);
}

float Iteration::eye_joint2_toward(const MisQuantities& eye_mis, const SubpathVertex& v,
                                   const Vec3& y, const Link& link) const {
    if (!plan_.joint2 || !(v.camera_joint_ratio > 0) || !v.in_medium() ||
        !v.medium->is_homogeneous() || !link.one_piece || !(link.densities.toward_start > 0))
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
    if (!plan_.joint || !(state.origin_joint_pdf > 0)) return;
    v.camera_joint_ratio =
        joint_pdf_l(state.origin_previous, state.origin, v.p) / state.origin_joint_pdf;
    mis_.include_joint_junction(mis, v.camera_joint_ratio);
}

void Iteration::joint_connections(const Ray& ray, const SubpathState& state, uint32_t first,
                                  uint32_t end, uint32_t rays_first, uint32_t rays_end, Rng& rng,
                                  RenderStats& stats, ContributionSink add) const {
    const Medium* medium = state.medium;
    // J1 at s = 1 is next-event estimation's sibling: there whenever next-event estimation is.
    const bool toward_light = 1 + state.path_length <= plan_.max_length;
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
        if (light_ray.path_length + 1 + state.path_length > plan_.max_length) break;
        Joint2Vertex b_joint2;
        if (const std::optional<LightVertex> b =
                resample_on_light_ray(light_ray, state.origin, ray.direction, b_joint2, rng)) {
            if (const std::optional<JointVertex> j = sample_vertex(b->p)) {
                if (const std::optional<ConnectionTerms> c =
                        connection_terms(*b, b_joint2, j->v, wo, j->mis, rng, stats, JointKind::J2))
                    add(b->path_length + 1, j->eye_weight * b->throughput * c->unoccluded *
                                                visibility(c->link, c->ray, stats));
            }
        }
    }
    for (uint32_t i = first; i < end; ++i) {
        const LightVertex& lv = light_vertices_[i];
        if (lv.path_length + 1 + state.path_length > plan_.max_length) break;
        const std::optional<JointVertex> j = sample_vertex(lv.p);
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
    Vertex v;
    v.p = b;
    v.medium = medium;
    v.phase = &medium->phase();
    v.previous = e.origin;
    joint2 = Joint2Vertex{};
    joint2.previous2 = e.origin_previous;
    joint2.light_ray_pdf = densities.toward_end;
    joint2.previous_light_ray_pdf = e.origin_light_ray_pdf;
    const Rgb throughput =
        e.throughput * medium->transmittance(ray, t, rng) * sigma_s * (1.0f / pdf);
    if (!throughput.is_finite() || throughput.is_black()) return std::nullopt;
    LightVertex lv(v, -e.direction, throughput, e.path_length, e.mis, e.finite_light);
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

}  // namespace render::bidirectional
