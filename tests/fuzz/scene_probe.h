#pragma once

// What the scene fuzz targets check of a scene that loaded, along the rays a render traces
// (docs/guide/reliability.md, "Fuzzing"):
//  - camera rays through a 4x4 grid of pixels are finite (Embree aborts on a NaN ray, killing
//    the worker) and can be traced (closest hit and occlusion);
//  - light paths: every light (the first 16) emits on a grid of samples, as a light path starts
//    (emission sampling); an emitted ray it accepts is finite and is traced as the integrators
//    spawn it; next-event estimation from the camera toward every light traces its shadow ray;
//  - rays through every instance (the first 16), from the camera and from each light's first
//    emitted origin, to the centre and corners of its world box.
// A scene the loader accepts must pass; abort() marks a finding. Rays Embree would refuse never
// reach it (Scene's guard, core/scene/embree_ray.h); a transform that makes a valid world ray
// invalid in an instance's space still would (an abort in Embree: a finding).

#include <cmath>
#include <cstdlib>
#include <vector>

#include "core/base/interaction.h"
#include "core/scene/scene.h"
#include "core/shapes/instance.h"

namespace render::fuzz {

inline bool finite(const Vec3& v) {
    return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

inline void trace(const Scene& scene, const Ray& ray) {
    SurfaceInteraction si;
    scene.intersect(ray, si);
    scene.occluded(ray);
}

constexpr size_t kProbedLights = 16, kProbedInstances = 16;

// Rays from `from` to the centre and the corners of every instance's world box.
inline void probe_instances_from(const Scene& scene, const Vec3& from) {
    size_t probed = 0;
    for (const auto& instance : scene.instances()) {
        if (++probed > kProbedInstances) break;
        const Aabb box = instance->bounds();
        for (int corner = 0; corner < 9; ++corner) {
            const Vec3 target = corner == 8 ? (box.lo + box.hi) * 0.5f
                                            : Vec3(corner & 1 ? box.hi.x : box.lo.x,
                                                   corner & 2 ? box.hi.y : box.lo.y,
                                                   corner & 4 ? box.hi.z : box.lo.z);
            const Vec3 d = target - from;
            if (!(length(d) > 0) || !finite(d)) continue;
            trace(scene, Ray(from, normalize(d)));
        }
    }
}

// Emitted rays of every light on a 3x3 grid of position samples by a 2x2 grid of direction
// samples, spawned as a light path spawns them (core/integrators/bidirectional/light_pass.cpp);
// returns the first emitted origin of each light that emitted.
inline std::vector<Vec3> probe_light_paths(const Scene& scene) {
    std::vector<Vec3> origins;
    size_t probed = 0;
    for (const auto& light : scene.lights()) {
        if (++probed > kProbedLights) break;
        bool first = true;
        for (int p = 0; p < 9; ++p)
            for (int q = 0; q < 4; ++q) {
                const Vec2 u_position((p % 3 + 0.5f) / 3, (p / 3 + 0.5f) / 3);
                const Vec2 u_direction((q % 2 + 0.25f) / 2, (q / 2 + 0.25f) / 2);
                LightEmitSample e;
                if (!light->emit(u_position, u_direction, e) || !(e.pdf_emission_w > 0)) continue;
                // A light path the integrators would trace: its ray must be finite.
                if (!finite(e.origin) || !finite(e.direction)) std::abort();
                if (first) origins.push_back(e.origin);
                first = false;
                trace(scene, light->is_finite()
                                 ? scene.spawn_ray(e.origin, e.direction, e.direction)
                                 : Ray(e.origin, e.direction));
            }
    }
    return origins;
}

// Next-event estimation from the camera's position toward every light: the shadow ray.
inline void probe_shadow_rays(const Scene& scene, const Vec3& from) {
    size_t probed = 0;
    for (const auto& light : scene.lights()) {
        if (++probed > kProbedLights) break;
        for (int k = 0; k < 4; ++k) {
            const Vec2 u((k % 2 + 0.5f) / 2, (k / 2 + 0.5f) / 2);
            LightIlluminateSample s;
            if (!light->illuminate(from, u, s) || !(s.pdf_direct_w > 0)) continue;
            if (!finite(s.wi)) std::abort();
            const float t_max = std::isfinite(s.distance) ? s.distance * (1 - 1e-4f) : kInfinity;
            scene.occluded(Ray(from, s.wi, 0, t_max));
        }
    }
}

inline void probe_scene(const Scene& scene) {
    const PerspectiveCamera& camera = scene.camera();
    for (int j = 0; j < 4; ++j)
        for (int i = 0; i < 4; ++i) {
            const Vec2 raster((i + 0.5f) * float(camera.width()) / 4,
                              (j + 0.5f) * float(camera.height()) / 4);
            const Ray ray = camera.generate_ray(raster);
            if (!finite(ray.origin) || !finite(ray.direction)) std::abort();
            trace(scene, ray);
        }
    const Vec3 eye = camera.position();
    probe_instances_from(scene, eye);
    probe_shadow_rays(scene, eye);
    for (const Vec3& origin : probe_light_paths(scene))
        if (finite(origin)) probe_instances_from(scene, origin);
}

}  // namespace render::fuzz
