#pragma once

// Textures (Mitsuba 3's `<texture>` plugins): an RGB value that varies over a surface, looked up
// at the hit's uv coordinates. BSDFs resolve their textured parameters once per hit
// (core/materials/textured_bsdf.h), so a texture is evaluated once per scattering vertex.

#include <memory>
#include <string>

#include "core/math/vec.h"

namespace render {

class Texture {
  public:
    virtual ~Texture() = default;

    // The linear RGB value at surface coordinates uv (before the texture's own to_uv).
    virtual Rgb eval(Vec2 uv) const = 0;
    // A single value (roughness), as Mitsuba's eval_1: the luminance of a colour, the value
    // itself (exactly) of a grey one.
    float eval_1(Vec2 uv) const { return to_scalar(eval(uv)); }
    static float to_scalar(const Rgb& c) { return c.r == c.g && c.g == c.b ? c.r : c.luminance(); }

    // Average over the texture's unit square of uv: stands for the texture where one value is
    // needed for the whole surface (descriptions, the BSDF an unresolved material falls back to).
    virtual Rgb mean() const = 0;
    // Smallest and largest channel value anywhere: parameters with a valid range (reflectances
    // in [0, 1], roughness >= 0) check the whole texture once when the material is built.
    virtual float min_value() const = 0;
    virtual float max_value() const = 0;

    virtual std::string to_string() const = 0;
};

}  // namespace render
