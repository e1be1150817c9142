#pragma once

// Lambertian reflection, one-sided (Mitsuba's `diffuse`): f = reflectance / pi when both
// directions are above the surface, zero otherwise. Samples the cosine-weighted hemisphere.

#include "core/base/properties.h"
#include "core/materials/bsdf.h"

namespace render {

class DiffuseBsdf final : public Bsdf {
  public:
    explicit DiffuseBsdf(const Rgb& reflectance) : reflectance_(reflectance) {}

    // Parameters: `reflectance` (rgb or float, default 0.5).
    static std::shared_ptr<const Bsdf> create(const Properties& props);

    Rgb f(const Vec3& wo, const Vec3& wi, TransportMode mode) const override;
    BsdfPdf pdf_w(const Vec3& wo, const Vec3& wi) const override;
    BsdfEvaluation evaluate(const Vec3& wo, const Vec3& wi, TransportMode mode) const override;
    std::optional<BsdfSample> sample(const Vec3& wo, float u_lobe, Vec2 u,
                                     TransportMode mode) const override;
    uint32_t lobes() const override { return kLobeDiffuseReflection; }
    std::string to_string() const override;

    const Rgb& reflectance() const { return reflectance_; }

  private:
    Rgb reflectance_;
};

}  // namespace render
