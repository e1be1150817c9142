#pragma once

// Which medium a path is in after crossing a surface. Mitsuba's rule: only transmission
// changes the medium, and the new one is the shape's interior when the direction goes against
// the geometric normal, its exterior otherwise; a side the shape does not declare is vacuum
// (null). A shape that declares no media therefore puts vacuum behind every transmission,
// which is what a glass object in fog needs when its own inside is empty.

#include "core/base/interaction.h"
#include "core/base/shape.h"
#include "core/math/vec.h"

namespace render {

class Medium;

inline const Medium* medium_after_transmission(const SurfaceInteraction& si, const Vec3& d) {
    return dot(d, si.geometric_normal) < 0 ? si.shape->interior : si.shape->exterior;
}

}  // namespace render
