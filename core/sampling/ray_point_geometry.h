#pragma once

// Where a point lies relative to a ray, in double: delta, the ray distance of the foot of the
// perpendicular from the point, and D, the perpendicular distance, clamped to 1e-6 of the
// problem's size (the range [t0, t1] and delta) so that a point (almost) on the ray's line
// still gives a finite density. Shared by the samplers whose densities depend on the distance
// to a point along a ray (equi-angular sampling, joint sampling's eye distance), so that they
// describe the same geometry.

#include <algorithm>
#include <cmath>

#include "core/math/vec.h"

namespace render {

struct RayPointGeometry {
    double delta = 0;     // ray distance of the foot of the perpendicular
    double distance = 0;  // perpendicular distance D (clamped, > 0 for a non-degenerate range)
};

inline RayPointGeometry ray_point_geometry(const Vec3& origin, const Vec3& direction,
                                           const Vec3& point, float t0, float t1) {
    const double lx = double(point.x) - origin.x, ly = double(point.y) - origin.y,
                 lz = double(point.z) - origin.z;
    RayPointGeometry g;
    g.delta = lx * direction.x + ly * direction.y + lz * direction.z;
    const double px = lx - g.delta * direction.x, py = ly - g.delta * direction.y,
                 pz = lz - g.delta * direction.z;
    const double scale = std::max({std::abs(double(t1) - t0), std::abs(g.delta), 1e-30});
    g.distance = std::max(std::sqrt(px * px + py * py + pz * pz), 1e-6 * scale);
    return g;
}

}  // namespace render
