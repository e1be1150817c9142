#pragma once

// Rough dielectric interface (Mitsuba's `roughdielectric`), the microfacet model of Walter et
// al. 2007, "Microfacet Models for Refraction through Rough Surfaces": reflection and
// refraction on a Beckmann or GGX surface, one of the two chosen by the Fresnel term of the
// sampled micro-normal. Either side may be the incident one.

#include "core/base/properties.h"
#include "core/materials/bsdf.h"
#include "core/materials/microfacet.h"

namespace render {

class RoughDielectricBsdf final : public Bsdf {
  public:
    // eta = n_inside / n_outside, != 1.
    RoughDielectricBsdf(const MicrofacetDistribution& distribution, float eta,
                        const Rgb& specular_reflectance, const Rgb& specular_transmission);

    // Parameters: those of `dielectric` plus `distribution` (default beckmann), `alpha`
    // (default 0.1) or `alpha_u`/`alpha_v`, `sample_visible` (default true).
    static std::shared_ptr<const Bsdf> create(const Properties& props);

    Rgb f(const Vec3& wo, const Vec3& wi, TransportMode mode) const override;
    BsdfPdf pdf_w(const Vec3& wo, const Vec3& wi) const override;
    std::optional<BsdfSample> sample(const Vec3& wo, float u_lobe, Vec2 u,
                                     TransportMode mode) const override;
    uint32_t lobes() const override { return kLobeGlossyReflection | kLobeGlossyTransmission; }
    std::string to_string() const override;

  private:
    // The generalised half vector of a direction pair (Walter's h_t for refraction), in the
    // upper hemisphere, with the relative IOR etap = n(wi side) / n(wo side). Nothing when the
    // pair is degenerate or the micro-normal would face away from one of the directions.
    struct HalfVector {
        Vec3 m;
        float etap;
    };
    std::optional<HalfVector> half_vector(const Vec3& wo, const Vec3& wi) const;
    // p(wi | wo) of sample().
    float sample_density(const Vec3& wo, const Vec3& wi) const;

    MicrofacetDistribution distribution_;
    float eta_;
    Rgb specular_reflectance_, specular_transmission_;
};

}  // namespace render
