#pragma once

// Mitsuba 3's `bumpmap` (and pbrt-v4's "texture displacement"): a nested BSDF seen in the
// shading frame of a surface displaced along its normal by a height texture h (times `scale`).
// With n the shading normal and dp/du, dp/dv the shape's tangents made orthogonal to n, the
// displaced surface has tangents dp/du + scale dh/du n and dp/dv + scale dh/dv n; their cross
// product (on n's side) is the new normal, and s is dp/du made orthogonal to it (Mitsuba's
// construction; normal_map.h has the Gram-Schmidt step). dh/du and dh/dv are central finite
// differences of the texture. Scene::intersect applies it (Bsdf::shading_frame) before it
// resolves the nested material at the hit.

#include <memory>

#include "core/base/properties.h"
#include "core/materials/shading_frame_bsdf.h"
#include "core/textures/texture.h"

namespace render {

class BumpMapBsdf final : public ShadingFrameBsdf {
  public:
    // Step in u and v of the finite differences: a power of two, small against any texture's
    // features and large against float spacing at uv ~ 1 (2^-24), which leaves ~1e-4 relative.
    static constexpr float kStep = 1.0f / 4096;

    BumpMapBsdf(std::shared_ptr<const Bsdf> nested, std::shared_ptr<const Texture> height,
                float scale);

    // One nested BSDF, one texture under any name (as Mitsuba) and the float `scale` (1).
    static std::shared_ptr<const Bsdf> create(const Properties& props);

    // scale (dh/du, dh/dv) at uv, by central differences of the texture's eval_1.
    Vec2 gradient(Vec2 uv) const;

    Frame shading_frame(const SurfaceInteraction& si) const override;
    std::string to_string() const override;

  private:
    std::shared_ptr<const Texture> height_;
    float scale_;
};

// The frame of the surface displaced by a height field with gradient `grad` (dh/du, dh/dv) at a
// point with shading frame `shading` and tangents dp/du, dp/dv. A zero gradient returns
// `shading` unchanged, and so does a point whose tangents do not span the tangent plane (a
// sphere's pole, degenerate uv).
Frame bump_mapped_frame(Vec2 grad, const Frame& shading, const Vec3& dpdu, const Vec3& dpdv);

}  // namespace render
