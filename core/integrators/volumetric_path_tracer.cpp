#include "core/integrators/volumetric_path_tracer.h"

#include <algorithm>
#include <cmath>
#include <optional>

#include "core/integrators/direct_light.h"
#include "core/integrators/medium_segment.h"
#include "core/integrators/mis.h"
#include "core/materials/surface_bsdf.h"
#include "core/media/medium.h"
#include "core/media/medium_interface.h"
#include "core/sampling/equiangular.h"
#include "core/sampling/joint_direction.h"
#include "core/sampling/joint_eye_distance.h"

namespace render {
namespace {

// A medium segment: the ray that crossed it and the distance range (0, t_end) that distance
// and equi-angular sampling covered.
struct MediumSegment {
    Ray ray;
    float t_end = 0;
    const Medium* medium = nullptr;
};

// U3 of a joint segment toward one light point, as J3 built it there: the densities of the
// segment's other vertices toward the same point (every vertex, with a point light) evaluate it
// instead of building it again.
struct JointEyeDensity {
    std::optional<JointEyeDistanceSampler> sampler;
    Vec3 light_point;
};

// The first medium vertex c of a pair (c, b) that joint sampling could have produced: its
// segment, distance on it and the densities with which distance and phase sampling produced c
// and the direction c -> b.
struct JointOrigin {
    bool valid = false;
    Vec3 p;
    MediumSegment segment;
    float t = 0;
    float distance_pdf_l = 0;
    float direction_pdf_w = 0;
    const JointEyeDensity* eye = nullptr;  // U3 on `segment`, when J3 built it
    // u3 u2 / shared of joint_pdf_ratio for `cached_light`: it depends on c, the direction
    // c -> b and the light point only, so the techniques on the segment from c (EL, DL, and
    // emission found there) share it.
    mutable bool cached = false;
    mutable Vec3 cached_light;
    mutable double cached_ratio = 0;
};

// The last real scattering vertex of the path, for weighting emission that the next segment
// finds by chance.
struct ScatteringVertex {
    Vec3 p;
    bool delta = true;  // camera or delta lobe: nothing else samples what it finds
    float direction_pdf_w = 0;
    bool in_medium = false;
    MediumSegment segment;  // the segment the medium vertex lies on
    float t = 0;            // its distance along that segment
    float distance_pdf_l = 0;
    bool joint_segment = false;  // a medium vertex on a segment where joint sampling runs
    JointOrigin joint;           // its predecessor, when joint sampling reaches this vertex too
};

class Tracer {
  public:
    Tracer(const Scene& scene, bool equiangular, VolptTechnique technique, Rng& rng,
           RenderStats& stats)
        : scene_(scene),
          equiangular_(equiangular),
          technique_(technique),
          rng_(rng),
          stats_(stats) {}

    // The weight of a technique other than J3 for a medium path that J3 produces with density
    // (ratio) `joint`: the power heuristic over the four, or the single-technique weights of
    // volpt_technique.h (`own` is the technique's own density, `others` those of DL, DP or EL).
    float weight(double own, double other1, double other2, double joint) const {
        switch (technique_) {
            case VolptTechnique::DistanceLight:
                return 1.0f;  // only DL runs and emission hits count 0 (emission_weight)
            case VolptTechnique::Joint:
                if (joint > 0) return 0.0f;  // J3 alone takes this path
                break;
            case VolptTechnique::All:
                break;
        }
        return power_heuristic4(own, other1, other2, joint);
    }

    // Density (per unit length) of equi-angular sampling of distance t on `segment` toward
    // `light_point` (zero on an unbounded segment or for an infinite light).
    static float segment_equiangular_pdf_l(const MediumSegment& segment, const Light* light,
                                           const Vec3& light_point, float t) {
        if (!light->is_finite() || !std::isfinite(segment.t_end)) return 0.0f;
        return EquiAngularSampler(segment.ray.origin, segment.ray.direction, light_point, 0.0f,
                                  segment.t_end)
            .pdf_l(t);
    }

    // Density of joint sampling (J3) producing the path ... c -> b -> light point, b at
    // distance t_cb on `segment_cb`, divided by the densities p_d(t_dc) p_phase(w_cb) that DL,
    // DP and EL share for c and w_cb, so that it compares with their remaining factors (per unit
    // length x solid angle at b). `light_pdf_w` is light sampling's density at b; `u1` the
    // equi-angular density of t_cb on `segment_cb` toward the light point
    // (segment_equiangular_pdf_l, which the caller has for EL's own weight). Zero when b has no
    // joint origin c or for infinite lights.
    static double joint_pdf_ratio(const JointOrigin& c, const MediumSegment& segment_cb,
                                  const Light* light, const Vec3& light_point, float light_pdf_w,
                                  float u1) {
        if (!c.valid || !light->is_finite()) return 0.0;
        if (!c.cached || !(c.cached_light == light_point)) {
            c.cached = true;
            c.cached_light = light_point;
            c.cached_ratio = joint_origin_ratio(c, segment_cb, light_point);
        }
        return c.cached_ratio * u1 * light_pdf_w;
    }

    // u3 u2 / shared of joint_pdf_ratio.
    static double joint_origin_ratio(const JointOrigin& c, const MediumSegment& segment_cb,
                                     const Vec3& light_point) {
        const double shared = double(c.distance_pdf_l) * c.direction_pdf_w;
        if (!(shared > 0)) return 0.0;
        const bool built = c.eye && c.eye->sampler && c.eye->light_point == light_point;
        const double u3 =
            built ? c.eye->sampler->pdf_l(c.t)
                  : JointEyeDistanceSampler(c.segment.ray.origin, c.segment.ray.direction,
                                            light_point, 0.0f, c.segment.t_end)
                        .pdf_l(c.t);
        const double u2 = JointDirectionSampler::pdf_w(c.p, light_point, segment_cb.ray.direction);
        return u3 * u2 / shared;
    }

    // The equi-angular density of t on `segment` toward `light_point` when EL or J3 needs it.
    static float el_or_joint_pdf_l(bool equiangular, const JointOrigin& joint,
                                   const MediumSegment& segment, const Light* light,
                                   const Vec3& light_point, float t) {
        return equiangular || joint.valid
                   ? segment_equiangular_pdf_l(segment, light, light_point, t)
                   : 0.0f;
    }

    // Transmittance from `p` along the light sample's direction to the light.
    Rgb light_visibility(const Vec3& p, const Vec3& n, const DirectLightSample& dl,
                         const Medium* medium) {
        const Ray shadow = dl.shadow_ray(scene_, p, n);
        if (!medium && !scene_.has_media()) {
            ++stats_.rays;
            return scene_.occluded(shadow) ? Rgb(0.0f) : Rgb(1.0f);
        }
        return connect_segment(scene_, shadow, medium, false, false, rng_, stats_).transmittance;
    }

    // Light sampling at a distance-sampled medium vertex (technique "DL").
    Rgb direct_light_in_medium(const ScatteringVertex& v, const Vec3& wo) {
        DirectLightSample dl;
        if (!sample_direct_light(scene_, v.p, rng_, dl)) return Rgb(0.0f);
        const LightIlluminateSample& ls = dl.ls;
        const float phase = v.segment.medium->phase().p(wo, ls.wi);
        if (!(phase > 0)) return Rgb(0.0f);
        const float light_pdf_w = dl.pdf_w();
        const Vec3 light_point = v.p + ls.wi * ls.distance;
        const float u1 =
            el_or_joint_pdf_l(equiangular_, v.joint, v.segment, dl.light, light_point, v.t);
        const float equiangular = equiangular_ ? u1 : 0.0f;
        const float w =
            weight(double(v.distance_pdf_l) * light_pdf_w,
                   dl.light->is_delta() ? 0.0 : double(v.distance_pdf_l) * phase,
                   double(equiangular) * light_pdf_w,
                   joint_pdf_ratio(v.joint, v.segment, dl.light, light_point, light_pdf_w, u1));
        if (!(w > 0)) return Rgb(0.0f);
        const Rgb tr = light_visibility(v.p, Vec3(0.0f), dl, v.segment.medium);
        return ls.radiance * tr * (phase * w / light_pdf_w);
    }

    // Equi-angular sampling of single scattering on a segment (technique "EL"): the light
    // point first, then the distance, then the connection. `joint` is the segment's origin
    // when joint sampling also produces these paths (its weight then includes J3).
    Rgb equiangular_inscattering(const MediumSegment& segment, const JointOrigin& joint) {
        float pick_probability = 0;
        const Light* light = scene_.sample_light(rng_.next_1d(), &pick_probability);
        const Vec2 u = rng_.next_2d();
        const float u_t = rng_.next_1d();
        Vec3 light_point;
        if (!light || !(pick_probability > 0) || !light->sample_position(u, light_point))
            return Rgb(0.0f);
        const EquiAngularSampler sampler(segment.ray.origin, segment.ray.direction, light_point,
                                         0.0f, segment.t_end);
        const float t = sampler.sample(u_t);
        const float equiangular = sampler.pdf_l(t);
        if (!(equiangular > 0)) return Rgb(0.0f);
        const Vec3 q = segment.ray.at(t);
        LightIlluminateSample ls;  // the same u picks the same light point (light.h)
        if (!light->illuminate(q, u, ls) || !(ls.pdf_direct_w > 0)) return Rgb(0.0f);
        const Medium& medium = *segment.medium;
        const float phase = medium.phase().p(-segment.ray.direction, ls.wi);
        const Rgb sigma_s = medium.sigma_s(q);
        if (!(phase > 0) || sigma_s.is_black()) return Rgb(0.0f);
        const float light_pdf_w = pick_probability * ls.pdf_direct_w;
        const float distance = medium.pdf_scatter_l(segment.ray, t);
        const float w =
            weight(double(equiangular) * light_pdf_w, double(distance) * light_pdf_w,
                   light->is_delta() ? 0.0 : double(distance) * phase,
                   joint_pdf_ratio(joint, segment, light, light_point, light_pdf_w, equiangular));
        if (!(w > 0)) return Rgb(0.0f);
        const Rgb tr_to_q = medium.transmittance(segment.ray, t, rng_);
        if (tr_to_q.is_black()) return Rgb(0.0f);
        const Rgb tr_to_light = light_visibility(
            q, Vec3(0.0f), DirectLightSample{light, pick_probability, ls}, segment.medium);
        return tr_to_q * sigma_s * ls.radiance * tr_to_light *
               (phase * w / (equiangular * light_pdf_w));
    }

    // Joint sampling of double scattering on a segment (technique "J3", Georgiev et al. 2013):
    // a light point a first, then the distance of c on the segment (U3), the direction from c
    // (U2), the distance of b on the ray from c to its first surface (U1, equi-angular toward
    // a), and the connection b -> a. The product of the densities cancels the geometry terms
    // G(c, b) G(b, a) (up to the truncation of U1 and the log-growing constant of U3), which
    // distance sampling leaves in the estimate near small lights. The segment must be in a
    // homogeneous medium with a finite end.
    // `eye` keeps U3 toward the light point for the densities of the segment's other vertices.
    Rgb joint_double_scattering(const MediumSegment& segment, JointEyeDensity& eye_density) {
        float pick_probability = 0;
        const Light* light = scene_.sample_light(rng_.next_1d(), &pick_probability);
        const Vec2 u_light = rng_.next_2d();
        const float u_dc = rng_.next_1d();
        const Vec2 u_direction = rng_.next_2d();
        const float u_cb = rng_.next_1d();
        Vec3 a;
        if (!light || !(pick_probability > 0) || !light->is_finite() ||
            !light->sample_position(u_light, a))
            return Rgb(0.0f);
        const Medium& medium = *segment.medium;

        eye_density.light_point = a;
        const JointEyeDistanceSampler& eye = eye_density.sampler.emplace(
            segment.ray.origin, segment.ray.direction, a, 0.0f, segment.t_end);
        const float t_dc = eye.sample(u_dc);
        const double pdf_dc = eye.pdf_l(t_dc);
        const Vec3 c = segment.ray.at(t_dc);
        float pdf_w_cb = 0;
        const Vec3 w_cb = JointDirectionSampler(c, a).sample(u_direction, pdf_w_cb);
        const float phase_c = medium.phase().p(-segment.ray.direction, w_cb);
        if (!(pdf_dc > 0) || !(pdf_w_cb > 0) || !(phase_c > 0)) return Rgb(0.0f);

        // The ray from c ends at its first surface (null boundaries included), as the segment
        // that distance sampling from c would cover.
        const Ray ray_cb(c, w_cb);
        SurfaceInteraction si(kUnfilled);
        ++stats_.rays;
        if (!scene_.intersect(ray_cb, si)) return Rgb(0.0f);
        const EquiAngularSampler toward_light(c, w_cb, a, 0.0f, si.t);
        const float t_cb = toward_light.sample(u_cb);
        const double pdf_cb = toward_light.pdf_l(t_cb);
        const Vec3 b = ray_cb.at(t_cb);
        LightIlluminateSample ls;  // the same u picks the same light point (light.h)
        if (!(pdf_cb > 0) || !light->illuminate(b, u_light, ls) || !(ls.pdf_direct_w > 0))
            return Rgb(0.0f);
        const float phase_b = medium.phase().p(-w_cb, ls.wi);
        const Rgb sigma_s = medium.sigma_s(c) * medium.sigma_s(b);
        if (!(phase_b > 0) || sigma_s.is_black()) return Rgb(0.0f);

        // MIS against DL, DP and EL at b, all in the measure dt_dc dw_cb dt_cb dw_ba. The medium
        // is homogeneous: distance sampling's density (spectral MIS) is (sigma_t T(t)).average()
        // (homogeneous_medium.cpp), from the transmittances the estimate needs anyway.
        const Rgb tr_dc = medium.transmittance(segment.ray, t_dc, rng_);
        const Rgb tr_cb = medium.transmittance(ray_cb, t_cb, rng_);
        const Rgb sigma_t = medium.sigma_t(c);
        const double light_pdf_w = double(pick_probability) * ls.pdf_direct_w;
        const double joint = pdf_dc * pdf_w_cb * pdf_cb * light_pdf_w;
        const double shared = double((sigma_t * tr_dc).average()) * phase_c;
        const double distance_cb = shared * (sigma_t * tr_cb).average();
        const float w = technique_ == VolptTechnique::Joint
                            ? 1.0f
                            : power_heuristic4(joint, distance_cb * light_pdf_w,
                                               light->is_delta() ? 0.0 : distance_cb * phase_b,
                                               equiangular_ ? shared * pdf_cb * light_pdf_w : 0.0);
        if (!(w > 0) || !(joint > 0) || !std::isfinite(joint)) return Rgb(0.0f);

        const Rgb tr = tr_dc * tr_cb;
        if (tr.is_black()) return Rgb(0.0f);
        const Rgb tr_to_light = light_visibility(
            b, Vec3(0.0f), DirectLightSample{light, pick_probability, ls}, segment.medium);
        return tr * sigma_s * ls.radiance * tr_to_light *
               float(double(phase_c) * phase_b * w / joint);
    }

    // Light sampling at a surface vertex.
    Rgb direct_light_at_surface(const SurfaceInteraction& si, const SurfaceBsdf& bsdf,
                                const Vec3& wo, const Medium* medium) {
        DirectLightSample dl;
        if (!sample_direct_light(scene_, si.p, rng_, dl)) return Rgb(0.0f);
        const LightIlluminateSample& ls = dl.ls;
        const auto [f, pdf_w] = bsdf.evaluate(wo, ls.wi);
        if (f.is_black()) return Rgb(0.0f);
        const float light_pdf_w = dl.pdf_w();
        const float w = dl.light->is_delta() || technique_ == VolptTechnique::DistanceLight
                            ? 1.0f
                            : power_heuristic(light_pdf_w, pdf_w.forward);
        // The shadow ray starts in the medium the rule gives its direction (medium_interface.h).
        const Medium* start = medium_after_surface(si, ls.wi, medium);
        const Rgb tr = light_visibility(si.p, si.geometric_normal, dl, start);
        return f * ls.radiance * tr * (bsdf.abs_cos_shading(ls.wi) * w / light_pdf_w);
    }

    // MIS weight of emission from `light` at `light_point` found by sampling a direction at
    // `v`; `pdf_direct_a` is light sampling's area density of that point (solid angle for
    // infinite lights, then `solid_angle` is true).
    float emission_weight(const ScatteringVertex& v, const Light* light, const Vec3& light_point,
                          float pdf_direct_a, float cos_light, bool solid_angle) const {
        if (v.delta) return 1.0f;
        if (technique_ == VolptTechnique::DistanceLight) return 0.0f;  // light sampling took it
        float light_pdf_w = scene_.light_pick_probability(light) * pdf_direct_a;
        if (!solid_angle) {  // area density so far: convert it to solid angle
            if (!(cos_light > 0)) return 0.0f;
            light_pdf_w *= length_squared(light_point - v.p) / cos_light;
        }
        if (!v.in_medium) return power_heuristic(v.direction_pdf_w, light_pdf_w);
        const float u1 = solid_angle ? 0.0f
                                     : el_or_joint_pdf_l(equiangular_, v.joint, v.segment, light,
                                                         light_point, v.t);
        const float equiangular = equiangular_ ? u1 : 0.0f;
        const double joint =
            solid_angle ? 0.0
                        : joint_pdf_ratio(v.joint, v.segment, light, light_point, light_pdf_w, u1);
        return weight(double(v.distance_pdf_l) * v.direction_pdf_w,
                      double(v.distance_pdf_l) * light_pdf_w, double(equiangular) * light_pdf_w,
                      joint);
    }

  private:
    const Scene& scene_;
    bool equiangular_;
    VolptTechnique technique_;
    Rng& rng_;
    RenderStats& stats_;
};

}  // namespace

bool VolumetricPathTracer::survives_roulette(int depth, Rgb& beta, Rng& rng) const {
    // Media of albedo 1 scatter without losing energy, so a path may take thousands of steps
    // before it reaches something that absorbs. Roulette therefore only acts on throughput
    // below 1 (as in pbrt-v4): capping survival at 0.95 like the surface path tracer would
    // cut almost every such path and leave an unbiased but useless heavy-tailed estimate.
    // The hard limit only guarantees termination (an infinite albedo-1 medium never absorbs).
    if (depth >= kMaxSegments) return false;
    if (depth < rr_depth_) return true;
    const float q = std::min(beta.max(), 1.0f);
    if (q >= 1.0f) return true;
    if (!(q > 0) || rng.next_1d() >= q) return false;
    beta *= 1.0f / q;
    return true;
}

Rgb VolumetricPathTracer::Li(const Scene& scene, const Ray& camera_ray, Rng& rng,
                             RenderStats& stats, const LayerSink& sink) const {
    Tracer tracer(scene, equiangular_, technique_, rng, stats);
    Rgb L(0.0f), beta(1.0f);
    Ray ray = camera_ray;
    const Medium* medium = scene.camera_medium();
    ScatteringVertex prev;
    prev.p = ray.origin;
    const bool has_lights = !scene.lights().empty();
    const bool can_extend_any = max_depth_ < 0;
    int null_crossings = 0;
    JointEyeDensity joint_eye;  // U3 on the camera segment (joint_double_scattering)

    // depth = segments of the path including `ray`
    for (int depth = 1;;) {
        const bool can_extend = can_extend_any || depth < max_depth_;
        SurfaceInteraction si;
        ++stats.rays;
        const bool hit = scene.intersect(ray, si);
        const float t_end = hit ? si.t : kInfinity;

        if (medium) {
            const MediumSegment segment{ray, t_end, medium};
            // Joint sampling also produces medium vertices on this segment when it left a
            // medium vertex c on a joint segment without crossing a boundary.
            JointOrigin joint_origin;
            if (prev.in_medium && prev.joint_segment && null_crossings == 0)
                joint_origin = JointOrigin{true,
                                           prev.p,
                                           prev.segment,
                                           prev.t,
                                           prev.distance_pdf_l,
                                           prev.direction_pdf_w,
                                           &joint_eye};
            if (equiangular_ && has_lights && can_extend && std::isfinite(t_end)) {
                const Rgb c = beta * tracer.equiangular_inscattering(segment, joint_origin);
                L += c;
                sink.add(Technique::Connection, 1, depth + 1, c);
            }
            // Joint sampling of double scattering on the camera ray's medium pieces (the
            // segment before the first scattering vertex), when two more segments are allowed.
            const bool joint_segment = jis_ && depth == 1 && has_lights &&
                                       medium->is_homogeneous() && std::isfinite(t_end) &&
                                       (can_extend_any || depth + 1 < max_depth_);
            if (joint_segment) {
                const Rgb c = beta * tracer.joint_double_scattering(segment, joint_eye);
                L += c;
                sink.add(Technique::Connection, 1, depth + 2, c);
            }
            const MediumSample ms = medium->sample(ray, t_end, rng);
            if (medium->is_emissive()) {
                // Emission along this segment (docs/design/media.md, "Emission in media"): only the
                // path finds it (no technique samples points of emissive media), so its MIS
                // weight is 1. Like a surface emitter hit at the segment's end, it belongs to
                // paths of `depth` segments.
                const Rgb c = beta * ms.emission;
                L += c;
                sink.add(Technique::Connection, 0, depth + 1, c);
            }
            beta *= ms.weight;
            if (beta.is_black() || !beta.is_finite()) break;
            if (ms.scattered) {
                if (!can_extend) break;
                ScatteringVertex v;
                v.p = ray.at(ms.t);
                v.delta = false;
                v.in_medium = true;
                v.segment = segment;
                v.t = ms.t;
                v.distance_pdf_l = medium->pdf_scatter_l(ray, ms.t);
                v.joint_segment = joint_segment;
                v.joint = joint_origin;
                const Vec3 wo = -ray.direction;
                if (has_lights) {
                    const Rgb c = beta * tracer.direct_light_in_medium(v, wo);
                    L += c;
                    sink.add(Technique::Connection, 1, depth + 1, c);
                }
                const PhaseSample ps = medium->phase().sample(wo, rng.next_2d());
                if (!(ps.pdf_w > 0)) break;
                v.direction_pdf_w = ps.pdf_w;
                prev = v;
                if (!survives_roulette(depth, beta, rng)) break;
                ray = Ray(v.p, ps.wi);
                ++depth;
                null_crossings = 0;
                continue;
            }
        }

        if (!hit) {
            for (const Light* light : scene.background_lights()) {
                const LightRadiance le = light->radiance(Vec3(), Vec3(), ray.direction);
                if (le.radiance.is_black()) continue;
                const Rgb c =
                    beta * le.radiance *
                    tracer.emission_weight(prev, light, Vec3(), le.pdf_direct_a, 1.0f, true);
                L += c;
                sink.add(Technique::Connection, 0, depth + 1, c);
            }
            break;
        }

        if (si.bsdf->is_null()) {
            // An index-matched boundary: only the medium changes.
            if (++null_crossings > kMaxNullCrossings) break;
            medium = medium_after_surface(si, ray.direction, medium);
            ray = scene.spawn_ray(si.p, si.geometric_normal, ray.direction);
            continue;
        }
        null_crossings = 0;

        if (si.emitter) {
            const LightRadiance le = si.emitter->radiance_at(si, ray.direction);
            if (!le.radiance.is_black()) {
                const float cos_light = abs_dot(si.geometric_normal, ray.direction);
                const Rgb c = beta * le.radiance *
                              tracer.emission_weight(prev, si.emitter, si.p, le.pdf_direct_a,
                                                     cos_light, false);
                L += c;
                sink.add(Technique::Connection, 0, depth + 1, c);
            }
        }
        if (!can_extend) break;

        const SurfaceBsdf bsdf(*si.bsdf, si.shading, si.geometric_normal, TransportMode::Radiance);
        const Vec3 wo = -ray.direction;
        if (has_lights && si.bsdf->has_non_delta()) {
            const Rgb c = beta * tracer.direct_light_at_surface(si, bsdf, wo, medium);
            L += c;
            sink.add(Technique::Connection, 1, depth + 1, c);
        }

        const float u_lobe = rng.next_1d();
        const std::optional<BsdfSample> bs = bsdf.sample(wo, u_lobe, rng.next_2d());
        if (!bs || bs->weight.is_black()) break;
        beta *= bs->weight;
        medium = medium_after_surface(si, bs->wi, medium);
        prev = ScatteringVertex{};
        prev.p = si.p;
        prev.delta = bs->delta;
        prev.direction_pdf_w = bs->pdf_w.forward;
        if (!survives_roulette(depth, beta, rng)) break;
        ray = scene.spawn_ray(si.p, si.geometric_normal, bs->wi);
        ++depth;
    }
    return L;
}

}  // namespace render
