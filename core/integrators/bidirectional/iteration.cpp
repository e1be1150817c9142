// The iteration's constructor (which clears the kept buffers) and the start and end of an eye
// subpath, which every eye pass shares.
#include "core/integrators/bidirectional/iteration.h"

#include <tbb/parallel_for.h>

namespace render::bidirectional {

Iteration::Iteration(const IterationPlan& plan, const Scene& scene, const IterationKey& key,
                     IterationStorage& storage)
    : plan_(plan),
      scene_(scene),
      key_(key),
      camera_(scene.camera()),
      mis_(plan.mis_power, plan.mis_techniques, double(plan.light_path_count)),
      storage_(storage),
      light_vertices_(storage.light_vertices),
      path_ends_(storage.path_ends),
      light_rays_(storage.light_rays),
      ray_ends_(storage.ray_ends),
      joint2_vertices_(storage.joint2_vertices),
      light_vertex_media_(storage.light_vertex_media),
      medium_positions_(storage.medium_positions),
      surface_index_(storage.surface_index),
      medium_index_(storage.medium_index),
      surface_grid_(storage.surface_grid),
      medium_grid_(storage.medium_grid) {
    medium_positions_.clear();
    for (auto* v : {&path_ends_, &surface_index_, &medium_index_}) v->clear();
    light_rays_.clear();
    ray_ends_.clear();
    joint2_vertices_.clear();
    light_vertex_media_.clear();
    // Destroying the last iteration's vertices reads all of them (hundreds of MB): in parallel
    // over the blocks.
    tbb::parallel_for(size_t(0), light_vertices_.block_count(),
                      [&](size_t b) { light_vertices_.clear_block(b); });
    light_vertices_.clear();
}

Ray Iteration::start_eye_path(uint64_t pixel, Rng& rng, SubpathState& state) const {
    const int width = camera_.width();
    const Vec2 jitter = rng.next_2d();
    Ray ray = camera_.sample_ray(
        Vec2(float(pixel % width) + jitter.x, float(pixel / width) + jitter.y), rng);
    state.throughput = Rgb(1.0f);
    state.initial_luminance = 1.0f;
    state.mis = mis_.start_camera(camera_pixel_pdf_w(ray.origin, ray.direction));
    state.medium = scene_.camera_medium();
    state.origin = ray.origin;
    return ray;
}

void Iteration::escaped_emission(SubpathState& state, const Ray& ray, const SampledSegment& seg,
                                 FunctionRef<void(const Rgb&)> add) const {
    // The distance sampling on the way is part of this technique's density; an infinite light
    // has no distance or cosine term.
    mis_.arrive(state.mis, 0.0f, false, 1.0f, seg.densities.toward_end, seg.densities.toward_start);
    mis_.add_photon_beam_term(state.mis, state.carried_photon_beam, 1.0f, seg.densities.toward_end,
                              seg.densities.toward_start, true, beam_segment(seg.densities));
    for (const Light* light : scene_.background_lights())
        add(state.throughput * emission(light, state,
                                        light->radiance(Vec3(), Vec3(), ray.direction), Vec3(),
                                        seg.medium));
}

SplatSink splats_into(AccumulationBuffer& target, TechniqueLayers* layers, RenderStats& stats,
                      const uint8_t* active) {
    return [&target, layers, &stats, active](std::span<const Splat> splats) {
        for (const Splat& splat : splats) {
            if (active && !active[splat.pixel]) continue;
            if (!splat.value.is_finite()) {
                ++stats.non_finite;
                continue;
            }
            target.add(splat.pixel, splat.value);
            if (layers)
                layers->add(layers->index(Technique::Connection, splat.light_vertices, 1),
                            splat.pixel, splat.value);
        }
    };
}

}  // namespace render::bidirectional
