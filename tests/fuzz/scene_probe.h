#pragma once

// What the scene fuzz targets check of a scene that loaded: the camera gives finite rays
// through a 4x4 grid of pixels (Embree aborts on a NaN ray, killing the worker), each of them
// can be traced (closest hit and occlusion), and so can rays from the camera through every
// instance. A scene the loader accepts must pass; abort() marks a finding.

#include <cmath>
#include <cstdlib>

#include "core/base/interaction.h"
#include "core/scene/scene.h"
#include "core/shapes/instance.h"

namespace render::fuzz {

inline bool finite(const Vec3& v) {
    return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

inline void probe_scene(const Scene& scene) {
    const PerspectiveCamera& camera = scene.camera();
    for (int j = 0; j < 4; ++j)
        for (int i = 0; i < 4; ++i) {
            const Vec2 raster((i + 0.5f) * float(camera.width()) / 4,
                              (j + 0.5f) * float(camera.height()) / 4);
            const Ray ray = camera.generate_ray(raster);
            if (!finite(ray.origin) || !finite(ray.direction)) std::abort();
            SurfaceInteraction si;
            scene.intersect(ray, si);
            scene.occluded(ray);
        }
    // Rays through every instance (the first 16): from the camera to the centre and the
    // corners of its world box, closest hit and occlusion. A transform that makes a valid world
    // ray invalid in the instance's space aborts in Embree here (a finding), whether or not a
    // camera ray of the grid above happened to cross it.
    const Vec3 eye = camera.position();
    size_t probed = 0;
    for (const auto& instance : scene.instances()) {
        if (++probed > 16) break;
        const Aabb box = instance->bounds();
        for (int corner = 0; corner < 9; ++corner) {
            const Vec3 target = corner == 8 ? (box.lo + box.hi) * 0.5f
                                            : Vec3(corner & 1 ? box.hi.x : box.lo.x,
                                                   corner & 2 ? box.hi.y : box.lo.y,
                                                   corner & 4 ? box.hi.z : box.lo.z);
            const Vec3 d = target - eye;
            if (!(length(d) > 0)) continue;
            const Ray ray(eye, normalize(d));
            SurfaceInteraction si;
            scene.intersect(ray, si);
            scene.occluded(ray);
        }
    }
}

}  // namespace render::fuzz
