#pragma once

#include "core/base/interaction.h"
#include "core/base/shape.h"
#include "core/materials/bsdf.h"

namespace render {

// Whether a hit on `shape` fills si.uv, si.dpdu and si.dpdv (HitDetail,
// core/base/interaction.h): when asked, or when the shape's material varies over the surface and
// so reads them in Scene::intersect (the shading-frame hook of normal and bump maps, at() of
// textures).
inline bool uv_wanted(const Shape& shape, HitDetail detail) {
    return detail == HitDetail::kWithUv || !shape.bsdf || shape.bsdf->varies();
}

}  // namespace render
