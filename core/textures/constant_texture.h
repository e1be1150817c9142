#pragma once

// A texture with one value everywhere: what a plain <rgb> or <float> becomes where a texture
// is expected inside another texture (checkerboard's color0 / color1). BSDF parameters keep
// plain constants as Rgb instead (textured_param.h), so untextured materials pay nothing.

#include <algorithm>
#include <sstream>

#include "core/textures/texture.h"

namespace render {

class ConstantTexture final : public Texture {
  public:
    explicit ConstantTexture(const Rgb& value) : value_(value) {}

    Rgb eval(Vec2) const override { return value_; }
    Rgb mean() const override { return value_; }
    float min_value() const override { return std::min(value_.r, std::min(value_.g, value_.b)); }
    float max_value() const override { return value_.max(); }
    std::string to_string() const override {
        std::ostringstream out;
        out << "constant" << value_;
        return out.str();
    }

  private:
    Rgb value_;
};

}  // namespace render
