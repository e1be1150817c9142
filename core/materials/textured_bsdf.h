#pragma once

// A material whose parameters are textures (Mitsuba's textured reflectance, roughness...).
// It is not evaluated itself: at every hit the scene asks it for the plain BSDF at the hit's uv
// (the same classes as untextured materials, built from the texture values there), so sampling,
// evaluation and both densities stay those of a plain BSDF, consistent by construction.
//
// Evaluated without a hit (nothing in the renderer does), it answers as `typical`, the BSDF
// built from the textures' mean values.

#include <functional>
#include <memory>
#include <string>

#include "core/materials/bsdf.h"

namespace render {

class TexturedBsdf final : public Bsdf {
  public:
    using Builder = std::function<std::shared_ptr<Bsdf>(Vec2 uv)>;

    TexturedBsdf(Builder build, std::shared_ptr<const Bsdf> typical, std::string description);

    std::shared_ptr<const Bsdf> at(Vec2 uv) const override;

    Rgb f(const Vec3& wo, const Vec3& wi, TransportMode mode) const override {
        return typical_->f(wo, wi, mode);
    }
    BsdfPdf pdf_w(const Vec3& wo, const Vec3& wi) const override { return typical_->pdf_w(wo, wi); }
    std::optional<BsdfSample> sample(const Vec3& wo, float u_lobe, Vec2 u,
                                     TransportMode mode) const override {
        return typical_->sample(wo, u_lobe, u, mode);
    }
    // Texture values change a lobe's weight, never which lobes there are.
    uint32_t lobes() const override { return typical_->lobes(); }
    std::string to_string() const override { return description_; }

  private:
    Builder build_;
    std::shared_ptr<const Bsdf> typical_;
    std::string description_;
};

// A material from its parameter readers: `build(&uv)` makes the plain BSDF from the parameters
// at uv, `build(nullptr)` from their means (constants: their value). An untextured material
// (`varies` false) is that one plain BSDF, exactly as without texture support.
template <class Build>
std::shared_ptr<const Bsdf> plain_or_textured(bool varies, const Build& build) {
    std::shared_ptr<const Bsdf> typical = build(nullptr);
    if (!varies) return typical;
    const std::string description = "textured " + typical->to_string();
    return std::make_shared<TexturedBsdf>(
        [build](Vec2 uv) -> std::shared_ptr<Bsdf> { return build(&uv); }, std::move(typical),
        description);
}

}  // namespace render
