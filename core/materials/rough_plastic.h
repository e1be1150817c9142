#pragma once

// Rough plastic (Mitsuba 3's `roughplastic`): a diffuse base under a rough dielectric coating.
// The coating reflects with the microfacet model of `roughdielectric`,
//     f_specular = ks F(wo.m) D(m) G(wo, wi, m) / (4 cos_o cos_i),   m = half vector,
// and the base scatters what the coating lets through, with the internal reflections at the
// coating summed in closed form as in `plastic`:
//     f_diffuse = kd / (1 - Ri) * T(cos_o) T(cos_i) / (pi eta^2)   (kd Ri when `nonlinear`).
// T(mu) is the rough interface's single-scattering transmittance from outside at cosine mu
// (tabulated at 64 cosines, linearly interpolated), Ri its hemispherical (cosine-weighted)
// reflectance from inside. Both depend only on the distribution, alpha and eta; they are
// integrated numerically once per material and shared by the per-hit BSDFs of a textured one.
// Sampling picks the specular lobe with probability proportional to (1 - T(cos_o)) ks_mean
// against T(cos_o) kd_mean, as Mitsuba. Isotropic roughness only; one-sided.

#include <array>
#include <memory>

#include "core/base/properties.h"
#include "core/materials/bsdf.h"
#include "core/materials/microfacet.h"

namespace render {

// Single-scattering albedos of a rough dielectric interface seen from a direction with cosine
// `cos_theta` > 0 on the side where n_other / n_this = `eta`: the fractions of light that leave
// after one microfacet event into the other medium (transmittance) or back (reflectance).
// Integrated over the visible normals with a Gauss-Legendre rule of `n` x `n` nodes.
float rough_interface_transmittance(const MicrofacetDistribution& distribution, float cos_theta,
                                    float eta, int n = 64);
float rough_interface_reflectance(const MicrofacetDistribution& distribution, float cos_theta,
                                  float eta, int n = 64);

// The coating's tables (T and Ri above) for one distribution, alpha and eta.
class RoughCoating {
  public:
    static constexpr int kTableSize = 64;

    RoughCoating(const MicrofacetDistribution& distribution, float eta);

    const MicrofacetDistribution& distribution() const { return distribution_; }
    float eta() const { return eta_; }
    // T(cos_theta), linearly interpolated in the table at cosines max(1e-6, i / 63).
    float transmittance(float cos_theta) const;
    // Ri = 2 * integral_0^1 R_inside(mu) mu dmu.
    float internal_reflectance() const { return internal_reflectance_; }

  private:
    MicrofacetDistribution distribution_;
    float eta_;
    std::array<float, kTableSize> transmittance_{};
    float internal_reflectance_ = 0;
};

class RoughPlasticBsdf final : public Bsdf {
  public:
    RoughPlasticBsdf(std::shared_ptr<const RoughCoating> coating, const Rgb& diffuse_reflectance,
                     const Rgb& specular_reflectance, bool nonlinear);

    // Parameters: `distribution` (beckmann, ggx; beckmann), `alpha` (0.1; a float, isotropic,
    // as Mitsuba 3), `sample_visible` (true), `diffuse_reflectance` (0.5),
    // `specular_reflectance` (1), `int_ior` (polypropylene), `ext_ior` (air), `nonlinear`
    // (false).
    static std::shared_ptr<const Bsdf> create(const Properties& props);

    Rgb f(const Vec3& wo, const Vec3& wi, TransportMode mode) const override;
    BsdfPdf pdf_w(const Vec3& wo, const Vec3& wi) const override;
    std::optional<BsdfSample> sample(const Vec3& wo, float u_lobe, Vec2 u,
                                     TransportMode mode) const override;
    uint32_t lobes() const override { return kLobeGlossyReflection | kLobeDiffuseReflection; }
    std::string to_string() const override;

  private:
    // Probability that sample() picks the specular lobe for a direction with this cosine.
    float specular_probability(float cos_theta) const;
    // p(wi | wo) of sample(), both lobes with their selection probabilities.
    float sample_density(const Vec3& wo, const Vec3& wi) const;

    std::shared_ptr<const RoughCoating> coating_;
    Rgb diffuse_reflectance_, specular_reflectance_;
    bool nonlinear_;
    Rgb diffuse_scaled_;  // kd / (1 - Ri) or kd / (1 - kd Ri), divided by pi eta^2
    float specular_sampling_weight_;
};

}  // namespace render
