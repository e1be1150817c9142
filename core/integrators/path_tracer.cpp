#include "core/integrators/path_tracer.h"

#include <algorithm>
#include <cmath>

#include "core/integrators/direct_light.h"
#include "core/integrators/mis.h"
#include "core/materials/surface_bsdf.h"

namespace render {

Rgb PathTracer::Li(const Scene& scene, const Ray& camera_ray, Rng& rng, RenderStats& stats,
                   const LayerSink& sink) const {
    Rgb L(0.0f), beta(1.0f);
    Ray ray = camera_ray;
    // Density (solid angle) of the BSDF sample that produced `ray`; a delta or camera
    // segment cannot be found by light sampling, so emission it finds is not weighted.
    float prev_bsdf_pdf = 0;
    bool prev_delta = true;
    const bool has_lights = !scene.lights().empty();

    for (int depth = 1;; ++depth) {        // depth = segments of the path including `ray`
        SurfaceInteraction si(kUnfilled);  // read only after a hit
        ++stats.rays;
        if (!scene.intersect(ray, si)) {
            for (const Light* light : scene.background_lights()) {
                LightRadiance le = light->radiance(Vec3(), Vec3(), ray.direction);
                if (le.radiance.is_black()) continue;
                float w = prev_delta
                              ? 1.0f
                              : power_heuristic(prev_bsdf_pdf, scene.light_pick_probability(light) *
                                                                   le.pdf_direct_a);
                const Rgb contribution = beta * le.radiance * w;
                L += contribution;
                // Emission found by the eye: s = 0 light vertices, t = depth + 1 eye vertices.
                sink.add(Technique::Connection, 0, depth + 1, contribution);
            }
            break;
        }

        if (si.emitter) {
            LightRadiance le = si.emitter->radiance_at(si, ray.direction);
            if (!le.radiance.is_black()) {
                float w = 1.0f;
                if (!prev_delta) {
                    // Light sampling's density for this point, converted to solid angle.
                    float cos_light = abs_dot(si.geometric_normal, ray.direction);
                    float light_pdf = cos_light > 0 ? scene.light_pick_probability(si.emitter) *
                                                          le.pdf_direct_a * si.t * si.t / cos_light
                                                    : 0.0f;
                    w = power_heuristic(prev_bsdf_pdf, light_pdf);
                }
                const Rgb contribution = beta * le.radiance * w;
                L += contribution;
                // Emission found by the eye: s = 0 light vertices, t = depth + 1 eye vertices.
                sink.add(Technique::Connection, 0, depth + 1, contribution);
            }
        }
        if (max_depth_ >= 0 && depth >= max_depth_) break;

        SurfaceBsdf bsdf(*si.bsdf, si.shading, si.geometric_normal, TransportMode::Radiance);
        const Vec3 wo = -ray.direction;

        // Next-event estimation.
        if (has_lights && si.bsdf->has_non_delta()) {
            DirectLightSample dl;
            if (sample_direct_light(scene, si.p, rng, dl)) {
                const LightIlluminateSample& ls = dl.ls;
                Rgb f = bsdf.f(wo, ls.wi);
                if (!f.is_black()) {
                    ++stats.rays;
                    if (!scene.occluded(dl.shadow_ray(scene, si.p, si.geometric_normal))) {
                        float light_pdf = dl.pdf_w();
                        float w = dl.light->is_delta()
                                      ? 1.0f
                                      : power_heuristic(light_pdf, bsdf.pdf_w(wo, ls.wi).forward);
                        const Rgb contribution =
                            beta * f * ls.radiance * (bsdf.abs_cos_shading(ls.wi) * w / light_pdf);
                        L += contribution;
                        sink.add(Technique::Connection, 1, depth + 1, contribution);
                    }
                }
            }
        }

        // Continue the path by sampling the BSDF.
        float u_lobe = rng.next_1d();
        std::optional<BsdfSample> bs = bsdf.sample(wo, u_lobe, rng.next_2d());
        if (!bs || bs->weight.is_black()) break;
        beta *= bs->weight;
        prev_delta = bs->delta;
        prev_bsdf_pdf = bs->pdf_w.forward;

        if (roulette_ == RoulettePolicy::Albedo) {
            if (!survives_albedo_roulette(bs->weight, beta, rng)) break;
        } else if (depth >= rr_depth_) {
            // Survive with probability proportional to the throughput (capped so that paths
            // carrying little energy are cut, and bright paths are never boosted beyond 1/0.95).
            float q = std::min(beta.max(), 0.95f);
            if (!(q > 0) || rng.next_1d() >= q) break;
            beta *= 1.0f / q;
        }
        ray = scene.spawn_ray(si.p, si.geometric_normal, bs->wi);
    }
    return L;
}

}  // namespace render
