#include "bench/bench_scenes.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <stdexcept>

#include "bench/procedural_mesh.h"
#include "core/materials/surface_bsdf.h"
#include "core/math/frame.h"
#include "core/sampling/rng.h"
#include "core/sampling/warp.h"
#include "core/scene/loader/scene_loader.h"

namespace render::bench {
namespace {

constexpr uint64_t kSeed = 20261122;
constexpr int kRayGrid = 256;  // camera rays per axis of the ray sets

std::mutex cache_mutex;

// The geometric normal turned toward the side the ray `d` arrived from.
Vec3 facing_normal(const SurfaceInteraction& si, const Vec3& d) {
    return dot(si.geometric_normal, d) < 0 ? si.geometric_normal : -si.geometric_normal;
}

// Follows a subpath from `ray`: at every hit whose BSDF has a non-delta lobe the position is
// stored; the next direction is sampled from the BSDF, and the path continues with probability
// min(sampled weight, 0.95) (about the albedo, as a throughput-driven Russian roulette would).
void trace_vertices(const Scene& scene, Ray ray, Rng& rng, TransportMode mode, int max_vertices,
                    std::vector<Vec3>& positions) {
    for (int vertices = 0; vertices < max_vertices; ++vertices) {
        SurfaceInteraction si;
        if (!scene.intersect(ray, si)) return;
        if (si.bsdf->has_non_delta()) positions.push_back(si.p);
        const SurfaceBsdf bsdf(*si.bsdf, si.shading, si.geometric_normal, mode);
        const float u_lobe = rng.next_1d();
        const std::optional<BsdfSample> bs = bsdf.sample(-ray.direction, u_lobe, rng.next_2d());
        if (!bs || rng.next_1d() >= std::min(bs->weight.max(), 0.95f)) return;
        ray = scene.spawn_ray(si.p, si.geometric_normal, bs->wi);
    }
}

}  // namespace

const std::vector<std::string>& ray_scene_names() {
    static const std::vector<std::string> names = {"cornell-box", "veach-mis",    "veach-bidir",
                                                   "0-gbs_s",     "1-glm_c",      "2-gbs_p",
                                                   "3-gbs_b",     "procedural-1M"};
    return names;
}

const std::vector<std::string>& media_scene_names() {
    static const std::vector<std::string> names = {"isosph", "glasssph", "volumetric-caustic",
                                                   "smoke"};
    return names;
}

const std::vector<std::string>& reference_scene_names() {
    static const std::vector<std::string> names = {"0-gbs_s", "1-glm_c", "2-gbs_p", "3-gbs_b"};
    return names;
}

std::filesystem::path scene_path(const std::string& name) {
    const std::filesystem::path root = RENDER_SOURCE_DIR;
    if (name == "cornell-box" || name == "veach-mis" || name == "veach-bidir" ||
        name == "volumetric-caustic")
        return root / "scenes" / "bitterli" / name / "scene_v3.xml";
    if (name == "isosph" || name == "glasssph")
        return root / "scenes" / "smallupbp" / (name + ".xml");
    if (name == "smoke") return root / "scenes" / "smoke" / "scene.xml";
    return root / "scenes" / "smallvcm" / (name + ".xml");
}

const Scene& scene(const std::string& name) {
    static std::map<std::string, std::unique_ptr<Scene>> scenes;
    std::lock_guard lock(cache_mutex);
    auto it = scenes.find(name);
    if (it == scenes.end()) {
        std::unique_ptr<Scene> s =
            name == "procedural-1M" ? make_procedural_scene() : load_scene(scene_path(name));
        it = scenes.emplace(name, std::move(s)).first;
    }
    return *it->second;
}

const RaySet& rays(const std::string& name) {
    const Scene& s = scene(name);
    static std::map<std::string, RaySet> sets;
    std::lock_guard lock(cache_mutex);
    auto it = sets.find(name);
    if (it != sets.end()) return it->second;
    RaySet set;
    const PerspectiveCamera& camera = s.camera();
    for (int y = 0; y < kRayGrid; ++y)
        for (int x = 0; x < kRayGrid; ++x) {
            Rng rng(StreamKey{kSeed, 0, 1, uint64_t(y) * kRayGrid + uint64_t(x)});
            const Vec2 raster((float(x) + rng.next_1d()) / kRayGrid * float(camera.width()),
                              (float(y) + rng.next_1d()) / kRayGrid * float(camera.height()));
            const Ray primary = camera.generate_ray(raster);
            set.closest.push_back(primary);
            SurfaceInteraction si;
            if (!s.intersect(primary, si)) continue;
            const Vec3 n = facing_normal(si, primary.direction);
            const Vec3 d =
                Frame::from_normal(n).to_world(warp::square_to_cosine_hemisphere(rng.next_2d()));
            set.closest.push_back(s.spawn_ray(si.p, n, d));
            float pick_probability = 0;
            const Light* light = s.sample_light(rng.next_1d(), &pick_probability);
            LightIlluminateSample ls;
            if (!light || !light->illuminate(si.p, rng.next_2d(), ls)) continue;
            set.shadow.push_back(std::isinf(ls.distance)
                                     ? s.spawn_ray_to_infinity(si.p, si.geometric_normal, ls.wi)
                                     : s.spawn_ray_to(si.p, si.geometric_normal,
                                                      si.p + ls.wi * ls.distance, Vec3()));
        }
    return sets.emplace(name, std::move(set)).first->second;
}

std::vector<Vec3> light_vertex_positions(const Scene& scene, uint64_t path_count,
                                         int max_vertices) {
    std::vector<Vec3> positions;
    for (uint64_t p = 0; p < path_count; ++p) {
        Rng rng(StreamKey{kSeed, 0, 1, (uint64_t(1) << 62) + p});
        float pick_probability = 0;
        const Light* light = scene.sample_light(rng.next_1d(), &pick_probability);
        const Vec2 u_position = rng.next_2d(), u_direction = rng.next_2d();
        LightEmitSample e;
        if (!light || !light->emit(u_position, u_direction, e)) continue;
        const Ray ray = light->is_finite() ? scene.spawn_ray(e.origin, e.direction, e.direction)
                                           : Ray(e.origin, e.direction);
        trace_vertices(scene, ray, rng, TransportMode::Importance, max_vertices, positions);
    }
    return positions;
}

std::vector<Vec3> eye_vertex_positions(const Scene& scene, int max_vertices) {
    std::vector<Vec3> positions;
    const PerspectiveCamera& camera = scene.camera();
    for (int y = 0; y < camera.height(); ++y)
        for (int x = 0; x < camera.width(); ++x) {
            Rng rng(StreamKey{kSeed, 0, 1, uint64_t(y) * uint64_t(camera.width()) + uint64_t(x)});
            const Vec2 raster(float(x) + rng.next_1d(), float(y) + rng.next_1d());
            trace_vertices(scene, camera.generate_ray(raster), rng, TransportMode::Radiance,
                           max_vertices, positions);
        }
    return positions;
}

}  // namespace render::bench
