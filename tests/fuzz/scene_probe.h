#pragma once

// What the scene fuzz targets check of a scene that loaded: the camera gives finite rays
// through a 4x4 grid of pixels (Embree aborts on a NaN ray, killing the worker), and each of
// them can be traced. A scene the loader accepts must pass; abort() marks a finding.

#include <cmath>
#include <cstdlib>

#include "core/base/interaction.h"
#include "core/scene/scene.h"

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
        }
}

}  // namespace render::fuzz
