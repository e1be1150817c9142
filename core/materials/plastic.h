#pragma once

// Smooth plastic (Mitsuba's `plastic`): a diffuse substrate under a smooth dielectric coating.
// Light either reflects specularly off the coating (weight F) or enters it, scatters diffusely
// and leaves through the coating, with the internal reflections at the coating summed in
// closed form:
//     f_diffuse = kd / (1 - Fdr_int) * (1 - F(cos_o)) (1 - F(cos_i)) / (pi eta^2),
// or kd / (1 - kd Fdr_int) when `nonlinear` (the colour shift of multiple bounces inside).
// The delta specular lobe is chosen with probability proportional to F * mean(ks) against
// (1 - F) * mean(kd), as in Mitsuba. One-sided.

#include "core/base/properties.h"
#include "core/materials/bsdf.h"

namespace render {

// The diffuse base of a plastic under a coating of relative IOR eta whose reflectance for light
// inside it is internal_reflectance (smooth: Fdr(1/eta); rough: Ri of the microfacet interface):
// kd / (1 - Ri) (or kd / (1 - kd Ri) when nonlinear), divided by pi eta^2, and the probability
// with which sampling picks the coating, mean(ks) / (mean(kd) + mean(ks)). PlasticBsdf and
// RoughPlasticBsdf share it.
struct PlasticBase {
    Rgb diffuse_scaled;
    float specular_sampling_weight;
};
PlasticBase plastic_base(const Rgb& diffuse_reflectance, const Rgb& specular_reflectance,
                         float internal_reflectance, float eta, bool nonlinear);

class PlasticBsdf final : public Bsdf {
  public:
    // eta = n_inside / n_outside of the coating.
    PlasticBsdf(const Rgb& diffuse_reflectance, const Rgb& specular_reflectance, float eta,
                bool nonlinear);

    // Parameters: `diffuse_reflectance` (0.5), `specular_reflectance` (1), `int_ior`
    // (polypropylene), `ext_ior` (air), `nonlinear` (false).
    static std::shared_ptr<const Bsdf> create(const Properties& props);

    Rgb f(const Vec3& wo, const Vec3& wi, TransportMode mode) const override;
    BsdfPdf pdf_w(const Vec3& wo, const Vec3& wi) const override;
    std::optional<BsdfSample> sample(const Vec3& wo, float u_lobe, Vec2 u,
                                     TransportMode mode) const override;
    uint32_t lobes() const override { return kLobeDeltaReflection | kLobeDiffuseReflection; }
    std::string to_string() const override;

  private:
    // Probability that sample() picks the specular lobe for a direction with this cosine.
    float specular_probability(float cos_theta) const;
    // p(wi | wo) of the diffuse lobe, including its selection probability.
    float sample_density(const Vec3& wo, const Vec3& wi) const;

    Rgb diffuse_reflectance_, specular_reflectance_;
    float eta_;
    bool nonlinear_;
    Rgb diffuse_scaled_;  // kd / (1 - Fdr_int) or kd / (1 - kd Fdr_int), divided by pi eta^2
    float specular_sampling_weight_;
};

}  // namespace render
