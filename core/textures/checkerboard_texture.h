#pragma once

// Mitsuba's `checkerboard`: with (s, t) = to_uv(uv), color0 where the fractional parts of s and
// t are both above 1/2 or both at most 1/2, color1 elsewhere: four squares per unit of uv.
// color0 / color1 may themselves be textures, looked up at the untransformed uv (as Mitsuba).

#include <memory>

#include "core/base/properties.h"
#include "core/textures/texture.h"
#include "core/textures/uv_transform.h"

namespace render {

class CheckerboardTexture final : public Texture {
  public:
    CheckerboardTexture(std::shared_ptr<const Texture> color0,
                        std::shared_ptr<const Texture> color1, const UvTransform& to_uv);

    // Parameters: `color0` (0.4), `color1` (0.2), each an rgb, a float or a texture; `to_uv`.
    static std::shared_ptr<const Texture> create(const Properties& props);

    Rgb eval(Vec2 uv) const override;
    // Each colour covers half of any unit square of (s, t).
    Rgb mean() const override { return (color0_->mean() + color1_->mean()) * 0.5f; }
    float min_value() const override;
    float max_value() const override;
    std::string to_string() const override;

  private:
    std::shared_ptr<const Texture> color0_, color1_;
    UvTransform to_uv_;
};

}  // namespace render
