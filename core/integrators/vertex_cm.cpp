#include "core/integrators/vertex_cm.h"

#include <tbb/blocked_range.h>
#include <tbb/combinable.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <climits>
#include <cmath>
#include <optional>
#include <vector>

#include "core/integrators/hash_grid.h"
#include "core/integrators/pixel_loop.h"
#include "core/integrators/vcm_mis.h"
#include "core/materials/surface_bsdf.h"
#include "core/math/constants.h"
#include "core/render/merge_radius.h"

namespace render {
namespace {

// Light paths draw from streams disjoint from the pixels' (stream = pixel index).
constexpr uint64_t kLightStreamBase = uint64_t(1) << 62;
// Light paths are traced in fixed chunks whose splats are added in chunk order, so the image
// does not depend on the number of threads.
constexpr uint64_t kLightPathChunk = 256;

// A subpath being extended: the throughput and the report's recursive MIS quantities.
struct SubpathState {
    Rgb throughput;
    float initial_luminance = 1;  // for Russian roulette relative to the start
    int path_length = 1;          // segments traced so far (the report's "path length")
    bool is_finite_light = true;  // light subpaths: the origin is a finite point
    bool specular_path = true;    // eye subpaths: every scattering so far was a delta lobe
    MisQuantities mis;
};

// A stored light-subpath vertex at a surface with a non-delta BSDF.
struct LightVertex {
    Vec3 position;
    Vec3 geometric_normal;
    Vec3 wo;  // toward the previous vertex of the light subpath
    Rgb throughput;
    int path_length;
    MisQuantities mis;
    SurfaceBsdf bsdf;  // importance transport
};

struct Splat {
    uint32_t pixel;
    Rgb value;
    int light_vertices;  // s of the (s, t = 1) technique, for the per-technique layers
};

// Everything one iteration shares between the light pass and the eye pass.
class Iteration {
  public:
    Iteration(const BidirectionalConfig& config, const Scene& scene, const IterationKey& key)
        : config_(config),
          scene_(scene),
          key_(key),
          camera_(scene.camera()),
          light_trace_only_(config.mode == BidirectionalMode::LightTracing),
          ppm_(config.mode == BidirectionalMode::Ppm),
          use_vc_(config.mode == BidirectionalMode::Bpt || config.mode == BidirectionalMode::Vcm),
          use_vm_(config.mode == BidirectionalMode::Ppm || config.mode == BidirectionalMode::Bpm ||
                  config.mode == BidirectionalMode::Vcm),
          max_length_(config.max_depth < 0 ? INT_MAX / 4 : config.max_depth),
          pixel_count_(uint64_t(camera_.width()) * uint64_t(camera_.height())),
          light_path_count_(config.light_path_count > 0 ? config.light_path_count : pixel_count_),
          radius_(merge_radius(config.radius_factor * scene.bounding_sphere().radius, config.alpha,
                               key.iteration)),
          // The report's eta_VCM = pi r^2 N_light: the ratio of merging to connection
          // densities of the same path.
          eta_vcm_(kPi * radius_ * radius_ * double(light_path_count_)),
          vm_normalization_(float(1.0 / eta_vcm_)),
          mis_(config.mis_power, use_vc_, use_vm_, eta_vcm_, double(light_path_count_)) {}

    void trace_light_paths(RenderStats& stats, std::vector<Splat>& splats);
    Rgb trace_eye_path(uint64_t pixel, RenderStats& stats, const LayerSink& sink) const;

  private:
    // Solid-angle density, per unit pixel area, of the camera producing world direction `dir`
    // (the report's camera pdf with the image plane measured in pixels).
    float camera_pixel_pdf_w(const Vec3& dir) const {
        return camera_.direction_pdf(dir) * float(pixel_count_);
    }

    bool generate_light_sample(Rng& rng, SubpathState& state, Ray& ray) const;
    void trace_light_path(uint64_t path_index, std::vector<LightVertex>& vertices,
                          std::vector<Splat>& splats, RenderStats& stats) const;
    bool sample_scattering(const SurfaceBsdf& bsdf, const SurfaceInteraction& si, const Vec3& wo,
                           Rng& rng, SubpathState& state, Ray& ray) const;
    void connect_to_camera(const SubpathState& state, const SurfaceInteraction& si,
                           const SurfaceBsdf& bsdf, const Vec3& wo, std::vector<Splat>& splats,
                           RenderStats& stats) const;
    Rgb emission(const Light* light, const SubpathState& state, const Vec3& hit_point,
                 const Vec3& hit_normal, const Vec3& ray_direction) const;
    Rgb direct_illumination(const SubpathState& state, const SurfaceInteraction& si,
                            const SurfaceBsdf& bsdf, const Vec3& wo, Rng& rng,
                            RenderStats& stats) const;
    Rgb connect_vertices(const LightVertex& light_vertex, const SurfaceInteraction& si,
                         const SurfaceBsdf& bsdf, const Vec3& wo, const SubpathState& state,
                         RenderStats& stats) const;
    Rgb merge(const SurfaceInteraction& si, const SurfaceBsdf& bsdf, const Vec3& wo,
              const SubpathState& state) const;

    const BidirectionalConfig& config_;
    const Scene& scene_;
    IterationKey key_;
    const PerspectiveCamera& camera_;
    bool light_trace_only_, ppm_, use_vc_, use_vm_;
    int max_length_;
    uint64_t pixel_count_, light_path_count_;
    double radius_;
    double eta_vcm_;
    float vm_normalization_;
    VcmMis mis_;

    std::vector<LightVertex> light_vertices_;
    std::vector<uint32_t> path_ends_;  // light_vertices_ of path p: [ends[p-1], ends[p])
    std::vector<Vec3> positions_;      // of light_vertices_, for the grid
    HashGrid grid_;
};

// --- light subpaths ---------------------------------------------------------------------------

bool Iteration::generate_light_sample(Rng& rng, SubpathState& state, Ray& ray) const {
    float pick_pdf = 0;
    const Light* light = scene_.sample_light(rng.next_1d(), &pick_pdf);
    Vec2 u_position = rng.next_2d(), u_direction = rng.next_2d();
    LightEmitSample e;
    if (!light || !(pick_pdf > 0) || !light->emit(u_position, u_direction, e)) return false;
    const float emission_pdf_w = e.pdf_emission_w * pick_pdf;
    const float direct_pdf_a = e.pdf_direct_a * pick_pdf;
    if (!(emission_pdf_w > 0)) return false;

    state.throughput = e.energy / emission_pdf_w;
    state.initial_luminance = std::max(state.throughput.max(), 1e-30f);
    state.path_length = 1;
    state.is_finite_light = light->is_finite();
    // Infinite lights have no cosine at the (virtual) emission point; a delta light cannot be
    // hit, so no technique ends on it by chance (eqs. 31-33).
    state.mis = mis_.start_light(direct_pdf_a, emission_pdf_w,
                                 light->is_finite() ? e.cos_at_light : 1.0f, light->is_delta());
    // Offsetting along the direction keeps the ray off the emitting surface.
    ray = light->is_finite() ? scene_.spawn_ray(e.origin, e.direction, e.direction)
                             : Ray(e.origin, e.direction);
    return state.throughput.is_finite();
}

void Iteration::trace_light_path(uint64_t path_index, std::vector<LightVertex>& vertices,
                                 std::vector<Splat>& splats, RenderStats& stats) const {
    Rng rng(StreamKey{key_.seed, key_.frame, key_.iteration, kLightStreamBase + path_index});
    SubpathState state;
    Ray ray;
    if (!generate_light_sample(rng, state, ray)) return;

    for (;; ++state.path_length) {
        SurfaceInteraction si;
        ++stats.rays;
        if (!scene_.intersect(ray, si)) break;
        const Vec3 wo = -ray.direction;
        const float cos_in = abs_dot(si.geometric_normal, wo);
        if (!(cos_in > 0)) break;
        // For infinite lights the first segment has no distance term.
        mis_.arrive(state.mis, si.t * si.t, state.path_length > 1 || state.is_finite_light, cos_in);

        const SurfaceBsdf bsdf(*si.bsdf, si.shading, si.geometric_normal,
                               TransportMode::Importance);
        // Delta BSDFs can neither be connected to nor merged at (the report's specular vertices).
        if (si.bsdf->has_non_delta()) {
            if (use_vc_ || use_vm_)
                vertices.push_back(LightVertex{si.p, si.geometric_normal, wo, state.throughput,
                                               state.path_length, state.mis, bsdf});
            if ((use_vc_ || light_trace_only_) && state.path_length + 1 <= max_length_)
                connect_to_camera(state, si, bsdf, wo, splats, stats);
        }
        // Extending needs one more segment plus at least the segment to the eye.
        if (state.path_length + 2 > max_length_) break;
        if (!sample_scattering(bsdf, si, wo, rng, state, ray)) break;
    }
}

void Iteration::trace_light_paths(RenderStats& stats, std::vector<Splat>& splats) {
    const uint64_t chunks = (light_path_count_ + kLightPathChunk - 1) / kLightPathChunk;
    std::vector<std::vector<LightVertex>> chunk_vertices(chunks);
    std::vector<std::vector<uint32_t>> chunk_path_sizes(chunks);
    std::vector<std::vector<Splat>> chunk_splats(chunks);
    tbb::combinable<RenderStats> chunk_stats;
    tbb::parallel_for(
        tbb::blocked_range<uint64_t>(0, chunks, 1), [&](const tbb::blocked_range<uint64_t>& range) {
            RenderStats& local = chunk_stats.local();
            for (uint64_t c = range.begin(); c < range.end(); ++c) {
                uint64_t first = c * kLightPathChunk;
                uint64_t end = std::min(first + kLightPathChunk, light_path_count_);
                for (uint64_t p = first; p < end; ++p) {
                    size_t before = chunk_vertices[c].size();
                    trace_light_path(p, chunk_vertices[c], chunk_splats[c], local);
                    chunk_path_sizes[c].push_back(uint32_t(chunk_vertices[c].size() - before));
                }
            }
        });
    chunk_stats.combine_each([&](const RenderStats& s) { stats += s; });

    // Concatenate in chunk order: deterministic whatever the thread count.
    path_ends_.clear();
    path_ends_.reserve(light_path_count_);
    uint32_t end = 0;
    for (uint64_t c = 0; c < chunks; ++c) {
        for (uint32_t size : chunk_path_sizes[c]) path_ends_.push_back(end += size);
        for (LightVertex& v : chunk_vertices[c]) light_vertices_.push_back(std::move(v));
        splats.insert(splats.end(), chunk_splats[c].begin(), chunk_splats[c].end());
    }
    if (use_vm_) {
        positions_.resize(light_vertices_.size());
        for (size_t i = 0; i < light_vertices_.size(); ++i)
            positions_[i] = light_vertices_[i].position;
        grid_.build(positions_, radius_);
    }
}

bool Iteration::sample_scattering(const SurfaceBsdf& bsdf, const SurfaceInteraction& si,
                                  const Vec3& wo, Rng& rng, SubpathState& state, Ray& ray) const {
    const float u_lobe = rng.next_1d();
    const Vec2 u = rng.next_2d();
    std::optional<BsdfSample> bs = bsdf.sample(wo, u_lobe, u);
    if (!bs || bs->weight.is_black()) return false;
    const float cos_out = abs_dot(si.geometric_normal, bs->wi);
    if (!(cos_out > 0)) return false;

    if (!bs->delta && !(bs->pdf.forward > 0)) return false;
    // Eqs. (34)-(36); Russian roulette below is deliberately not part of the densities.
    mis_.scatter(state.mis, cos_out, bs->pdf.forward, bs->pdf.reverse, bs->delta);
    state.specular_path = state.specular_path && bs->delta;
    state.throughput *= bs->weight;

    if (state.path_length >= config_.rr_depth) {
        const float q = std::min(0.95f, state.throughput.max() / state.initial_luminance);
        if (!(q > 0) || rng.next_1d() >= q) return false;
        state.throughput *= 1.0f / q;
    }
    ray = scene_.spawn_ray(si.p, si.geometric_normal, bs->wi);
    return true;
}

void Iteration::connect_to_camera(const SubpathState& state, const SurfaceInteraction& si,
                                  const SurfaceBsdf& bsdf, const Vec3& wo,
                                  std::vector<Splat>& splats, RenderStats& stats) const {
    std::optional<Vec2> raster = camera_.raster_position(si.p);
    if (!raster) return;
    const Vec3 to_camera = camera_.position() - si.p;
    const float dist2 = length_squared(to_camera);
    if (!(dist2 > 0)) return;
    const Vec3 d = to_camera / std::sqrt(dist2);
    const auto [f, pdf] = bsdf.evaluate(wo, d);
    if (f.is_black()) return;
    const float camera_pdf_w = camera_pixel_pdf_w(-d);
    const float cos_geometric = abs_dot(si.geometric_normal, d);
    // The camera's area density at this vertex (eq. 46).
    const float camera_pdf_a = camera_pdf_w * cos_geometric / dist2;
    const float weight =
        light_trace_only_ ? 1.0f : mis_.weight_camera(state.mis, camera_pdf_a, pdf.reverse);
    const Rgb contribution =
        state.throughput * f *
        (weight * camera_pdf_w * bsdf.abs_cos_shading(d) / (dist2 * float(light_path_count_)));
    if (contribution.is_black()) return;
    ++stats.rays;
    if (scene_.occluded(scene_.spawn_ray_to(si.p, si.geometric_normal, camera_.position(), Vec3())))
        return;
    const uint32_t x = std::min(uint32_t(raster->x), uint32_t(camera_.width() - 1));
    const uint32_t y = std::min(uint32_t(raster->y), uint32_t(camera_.height() - 1));
    splats.push_back(Splat{y * uint32_t(camera_.width()) + x, contribution, state.path_length + 1});
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
    const float pick = scene_.light_pdf(light);
    return le.radiance *
           mis_.weight_emission(state.mis, le.pdf_direct_a * pick, le.pdf_emission_w * pick);
}

Rgb Iteration::direct_illumination(const SubpathState& state, const SurfaceInteraction& si,
                                   const SurfaceBsdf& bsdf, const Vec3& wo, Rng& rng,
                                   RenderStats& stats) const {
    float pick = 0;
    const Light* light = scene_.sample_light(rng.next_1d(), &pick);
    const Vec2 u = rng.next_2d();
    LightIlluminateSample ls;
    if (!light || !(pick > 0) || !light->illuminate(si.p, u, ls) || !(ls.pdf_direct_w > 0))
        return Rgb(0.0f);
    const auto [f, pdf] = bsdf.evaluate(wo, ls.wi);
    if (f.is_black()) return Rgb(0.0f);
    // Eqs. (44) and (45).
    const float weight = mis_.weight_direct(
        state.mis, pdf.forward, pdf.reverse, pick * ls.pdf_direct_w, ls.pdf_emission_w,
        ls.pdf_direct_w, abs_dot(si.geometric_normal, ls.wi), ls.cos_at_light, light->is_delta());
    const Rgb contribution =
        ls.radiance * f * (weight * bsdf.abs_cos_shading(ls.wi) / (pick * ls.pdf_direct_w));
    if (contribution.is_black()) return Rgb(0.0f);
    ++stats.rays;
    const Ray shadow =
        std::isinf(ls.distance)
            ? scene_.spawn_ray_to_infinity(si.p, si.geometric_normal, ls.wi)
            : scene_.spawn_ray_to(si.p, si.geometric_normal, si.p + ls.wi * ls.distance, Vec3());
    return scene_.occluded(shadow) ? Rgb(0.0f) : contribution;
}

Rgb Iteration::connect_vertices(const LightVertex& lv, const SurfaceInteraction& si,
                                const SurfaceBsdf& bsdf, const Vec3& wo, const SubpathState& state,
                                RenderStats& stats) const {
    Vec3 d = lv.position - si.p;
    const float dist2 = length_squared(d);
    if (!(dist2 > 0)) return Rgb(0.0f);
    d = d / std::sqrt(dist2);
    const auto [f_eye, pdf_eye] = bsdf.evaluate(wo, d);
    if (f_eye.is_black()) return Rgb(0.0f);
    const auto [f_light, pdf_light] = lv.bsdf.evaluate(lv.wo, -d);
    if (f_light.is_black()) return Rgb(0.0f);
    // Area densities of extending either subpath to the other's endpoint.
    const float eye_pdf_a = pdf_eye.forward * abs_dot(lv.geometric_normal, d) / dist2;
    const float light_pdf_a = pdf_light.forward * abs_dot(si.geometric_normal, d) / dist2;
    // Eqs. (40) and (41).
    const float weight = mis_.weight_connection(lv.mis, state.mis, eye_pdf_a, light_pdf_a,
                                                pdf_light.reverse, pdf_eye.reverse);
    const float geometry = bsdf.abs_cos_shading(d) * lv.bsdf.abs_cos_shading(d) / dist2;
    const Rgb contribution = f_eye * f_light * (geometry * weight);
    if (contribution.is_black()) return Rgb(0.0f);
    ++stats.rays;
    if (scene_.occluded(
            scene_.spawn_ray_to(si.p, si.geometric_normal, lv.position, lv.geometric_normal)))
        return Rgb(0.0f);
    return contribution;
}

Rgb Iteration::merge(const SurfaceInteraction& si, const SurfaceBsdf& bsdf, const Vec3& wo,
                     const SubpathState& state) const {
    Rgb sum(0.0f);
    grid_.for_each_within_radius(si.p, [&](uint32_t index) {
        const LightVertex& lv = light_vertices_[index];
        if (lv.path_length + state.path_length > max_length_) return;
        // The photon arrived from lv.wo; the eye vertex scatters it toward wo.
        const auto [f, pdf] = bsdf.evaluate(wo, lv.wo);
        if (f.is_black()) return;
        float weight = 1.0f;
        if (!ppm_) {
            // Eqs. (38) and (39).
            weight = mis_.weight_merge(lv.mis, state.mis, pdf.forward, pdf.reverse);
        }
        sum += f * lv.throughput * weight;
    });
    return sum * vm_normalization_;
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

    Rgb color(0.0f);
    // s light vertices and t = path_length + 1 eye vertices (the camera included).
    auto add = [&](Technique kind, int s, const Rgb& contribution) {
        color += contribution;
        sink.add(kind, s, state.path_length + 1, contribution);
    };
    for (;; ++state.path_length) {
        SurfaceInteraction si;
        ++stats.rays;
        if (!scene_.intersect(ray, si)) {
            for (const Light* light : scene_.background_lights())
                add(Technique::Connection, 0,
                    state.throughput * emission(light, state, Vec3(), Vec3(), ray.direction));
            break;
        }
        const Vec3 wo = -ray.direction;
        const float cos_in = abs_dot(si.geometric_normal, wo);
        if (!(cos_in > 0)) break;
        mis_.arrive(state.mis, si.t * si.t, true, cos_in);

        if (si.emitter)
            add(Technique::Connection, 0,
                state.throughput *
                    emission(si.emitter, state, si.p, si.geometric_normal, ray.direction));
        if (state.path_length >= max_length_) break;

        const SurfaceBsdf bsdf(*si.bsdf, si.shading, si.geometric_normal, TransportMode::Radiance);
        // Light tracing and PPM leave every non-delta scattering of the eye path to the light
        // paths (camera connections or the one merge); the eye continues only through delta
        // lobes, including the delta lobes of mixed materials such as plastic's coating.
        const bool eye_ends_at_non_delta = light_trace_only_ || ppm_;
        if (si.bsdf->has_non_delta() && !light_trace_only_) {
            if (use_vc_) {
                add(Technique::Connection, 1,
                    state.throughput * direct_illumination(state, si, bsdf, wo, rng, stats));
            }
            if (use_vc_ && !path_ends_.empty()) {
                const uint64_t path = pixel % light_path_count_;
                const uint32_t first = path == 0 ? 0 : path_ends_[path - 1];
                for (uint32_t i = first; i < path_ends_[path]; ++i) {
                    const LightVertex& lv = light_vertices_[i];
                    if (lv.path_length + 1 + state.path_length > max_length_) break;
                    add(Technique::Connection, lv.path_length + 1,
                        state.throughput * lv.throughput *
                            connect_vertices(lv, si, bsdf, wo, state, stats));
                }
            }
            if (use_vm_) {
                add(Technique::Merging, 0, state.throughput * merge(si, bsdf, wo, state));
            }
        }
        if (eye_ends_at_non_delta && !si.bsdf->has_delta()) break;
        if (!sample_scattering(bsdf, si, wo, rng, state, ray)) break;
        if (eye_ends_at_non_delta && !state.specular_path) break;
    }
    return color;
}

}  // namespace

void VertexConnectionMerging::render_iteration(const Scene& scene, const IterationKey& key,
                                               AccumulationBuffer& target, TechniqueLayers* layers,
                                               RenderStats& stats) const {
    Iteration iteration(config_, scene, key);
    std::vector<Splat> splats;
    if (!scene.lights().empty()) iteration.trace_light_paths(stats, splats);
    for (const Splat& splat : splats) {
        if (!splat.value.is_finite()) {
            ++stats.non_finite;
            continue;
        }
        target.add(splat.pixel, splat.value);
        if (layers)
            layers->add(layers->index(Technique::Connection, splat.light_vertices, 1), splat.pixel,
                        splat.value);
    }

    const int width = scene.camera().width(), height = scene.camera().height();
    for_each_pixel(width, height, target, stats, [&](uint64_t pixel, RenderStats& local) {
        return iteration.trace_eye_path(pixel, local, LayerSink{layers, pixel});
    });
}

}  // namespace render
