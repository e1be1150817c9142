#pragma once

// A material or light parameter that is either a constant or a texture. Constants stay plain
// values, so materials without textures are built and evaluated exactly as before.

#include <memory>

#include "core/textures/texture.h"

namespace render {

struct RgbParam {
    Rgb value;                               // used when texture is null
    std::shared_ptr<const Texture> texture;  // looked up at the hit's uv

    bool varies() const { return texture != nullptr; }
    Rgb at(Vec2 uv) const { return texture ? texture->eval(uv) : value; }
    Rgb mean() const { return texture ? texture->mean() : value; }
    // At *uv, or the mean when uv is null (the material's typical BSDF).
    Rgb at(const Vec2* uv) const { return uv ? at(*uv) : mean(); }
};

struct FloatParam {
    float value = 0;
    std::shared_ptr<const Texture> texture;  // as a single value (Texture::eval_1)

    bool varies() const { return texture != nullptr; }
    float at(Vec2 uv) const { return texture ? texture->eval_1(uv) : value; }
    float mean() const { return texture ? Texture::to_scalar(texture->mean()) : value; }
    float at(const Vec2* uv) const { return uv ? at(*uv) : mean(); }
};

}  // namespace render
