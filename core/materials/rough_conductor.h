#pragma once

// Rough conductor (Mitsuba's `roughconductor`): the Torrance-Sparrow / Cook-Torrance microfacet
// reflection model f = F(wo.m) D(m) G(wo, wi, m) / (4 cos_o cos_i), m = half vector, with a
// Beckmann or GGX distribution and the exact conductor Fresnel term. One-sided.

#include "core/base/properties.h"
#include "core/materials/bsdf.h"
#include "core/materials/ior.h"
#include "core/materials/microfacet.h"

namespace render {

class RoughConductorBsdf final : public Bsdf {
  public:
    // `ior` absent: no Fresnel term (reflectance 1).
    RoughConductorBsdf(const MicrofacetDistribution& distribution, std::optional<ConductorIor> ior,
                       const Rgb& specular_reflectance);

    // Parameters: those of `conductor` plus `distribution` (beckmann, ggx; default beckmann),
    // `alpha` (default 0.1) or `alpha_u`/`alpha_v`, `sample_visible` (default true).
    static std::shared_ptr<const Bsdf> create(const Properties& props);

    Rgb f(const Vec3& wo, const Vec3& wi, TransportMode mode) const override;
    BsdfPdf pdf_w(const Vec3& wo, const Vec3& wi) const override;
    std::optional<BsdfSample> sample(const Vec3& wo, float u_lobe, Vec2 u,
                                     TransportMode mode) const override;
    uint32_t lobes() const override { return kLobeGlossyReflection; }
    std::string to_string() const override;

  private:
    // p(wi | wo) of sample().
    float sample_density(const Vec3& wo, const Vec3& wi) const;
    Rgb fresnel(float cos_theta) const;

    MicrofacetDistribution distribution_;
    std::optional<ConductorIor> ior_;
    Rgb specular_reflectance_;
};

}  // namespace render
