#pragma once

// The normalised modified Phong model with Mitsuba 0.6's semantics:
//     f = kd / pi + ks (n + 2) / (2 pi) max(0, reflect(wo) . wi)^n,
// zero unless both directions are above the surface. Its albedo never exceeds kd + ks, and
// reaches ks for the specular part at normal incidence. Sampling picks the diffuse or the
// specular lobe in proportion to mean(kd) : mean(ks), the latter with a cos^n lobe about the
// mirror direction (samples below the surface are rejected), and reports the mixture pdf.
// This is the glossy floor of the reference Cornell boxes.

#include "core/base/properties.h"
#include "core/materials/bsdf.h"

namespace render {

class PhongBsdf final : public Bsdf {
  public:
    PhongBsdf(const Rgb& diffuse_reflectance, const Rgb& specular_reflectance, float exponent);

    // Parameters: `diffuse_reflectance` (0.5), `specular_reflectance` (0.2), `exponent` (30).
    static std::shared_ptr<const Bsdf> create(const Properties& props);

    Rgb f(const Vec3& wo, const Vec3& wi, TransportMode mode) const override;
    BsdfPdf pdf_w(const Vec3& wo, const Vec3& wi) const override;
    // One power of the lobe's cosine for f and both densities.
    BsdfEvaluation evaluate(const Vec3& wo, const Vec3& wi, TransportMode mode) const override;
    std::optional<BsdfSample> sample(const Vec3& wo, float u_lobe, Vec2 u,
                                     TransportMode mode) const override;
    uint32_t lobes() const override { return kLobeDiffuseReflection | kLobeGlossyReflection; }
    std::string to_string() const override;

  private:
    Rgb diffuse_reflectance_, specular_reflectance_;
    float exponent_;
    float specular_sampling_weight_;  // probability of sampling the specular lobe
};

}  // namespace render
