#pragma once

#include <memory>

#include "core/media/medium.h"

namespace render {

// Constant coefficients everywhere: analytic distance sampling and transmittance.
class HomogeneousMedium final : public Medium {
  public:
    // `radiance` is the emitted radiance L_e (source term sigma_a L_e); zero: no emission.
    HomogeneousMedium(const Rgb& sigma_a, const Rgb& sigma_s,
                      std::shared_ptr<const PhaseFunction> phase, const Rgb& radiance = Rgb(0.0f));

    MediumSample sample(const Ray& ray, float t_max, Rng& rng) const override;
    Rgb transmittance(const Ray& ray, float t_max, Rng& rng) const override;
    float pdf_scatter_l(const Ray& ray, float t) const override;
    float probability_pass(const Ray& ray, float t) const override;
    Rgb sigma_s(const Vec3&) const override { return sigma_s_; }
    Rgb sigma_t(const Vec3&) const override { return sigma_t_; }
    const PhaseFunction& phase() const override { return *phase_; }
    bool is_homogeneous() const override { return true; }
    bool is_emissive() const override { return emissive_; }
    Rgb radiance(const Vec3&) const override { return radiance_; }
    std::string to_string() const override;

    // exp(-sigma_t t) per channel; exactly 1 at t = 0 and 0 at t = infinity.
    Rgb transmittance(float t) const;

  private:
    // The emission integral of medium.h over (0, t_max), in closed form:
    // sigma_a L_e (1 - exp(-sigma_t t_max)) / sigma_t per channel.
    Rgb emission(float t_max) const;

    Rgb sigma_s_, sigma_t_, radiance_;
    bool emissive_;
    std::shared_ptr<const PhaseFunction> phase_;
};

}  // namespace render
