#pragma once

// Mitsuba's `normalmap`: a nested BSDF seen in a shading frame tilted by a normal map. The
// map's RGB at the hit's uv gives the normal n' = normalize(2 rgb - 1) in the tangent frame
// (s along dp/du made orthogonal to the shading normal n, t = n x s, n); the nested BSDF is
// then evaluated in the frame of n' (its s again along dp/du). Scene::intersect applies it
// (Bsdf::shading_frame) before it resolves the nested material at the hit.

#include <memory>

#include "core/base/properties.h"
#include "core/materials/shading_frame_bsdf.h"
#include "core/textures/texture.h"

namespace render {

class NormalMapBsdf final : public ShadingFrameBsdf {
  public:
    // `map`: a texture, or null with the constant colour `constant`.
    NormalMapBsdf(std::shared_ptr<const Bsdf> nested, std::shared_ptr<const Texture> map,
                  Rgb constant);

    // One nested BSDF and the `normalmap` texture (or an rgb constant).
    static std::shared_ptr<const Bsdf> create(const Properties& props);

    // The normal map's frame at the hit's uv, from its shading frame and dp/du (world space).
    Frame shading_frame(const SurfaceInteraction& si) const override;
    std::string to_string() const override;

  private:
    std::shared_ptr<const Texture> map_;
    Rgb constant_;
};

// The frame of the tangent-space normal `local` (need not be unit) at a point with shading
// frame `shading` and tangent dp/du: s along dp/du made orthogonal to the normal (any
// orthogonal s when dp/du is zero or parallel to it). A flat normal (0, 0, z > 0) returns
// `shading` unchanged; a zero one too.
Frame normal_mapped_frame(const Vec3& local, const Frame& shading, const Vec3& dpdu);

// The frame of unit normal `n` with s along dp/du made orthogonal to it (any orthogonal s when
// dp/du is zero or parallel to n): Mitsuba's Gram-Schmidt step, shared with bump maps.
Frame frame_with_tangent(const Vec3& n, const Vec3& dpdu);

}  // namespace render
