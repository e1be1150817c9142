#pragma once

// Smooth dielectric interface (Mitsuba's `dielectric`): delta reflection and delta refraction,
// one of the two chosen with probability equal to its Fresnel weight, so the sampling weight is
// the specular_reflectance or specular_transmission tint (times the 1/eta^2 radiance scaling
// of refraction in Radiance mode).

#include "core/base/properties.h"
#include "core/materials/bsdf.h"

namespace render {

class DielectricBsdf final : public Bsdf {
  public:
    // eta = n_inside / n_outside.
    DielectricBsdf(float eta, const Rgb& specular_reflectance, const Rgb& specular_transmission);

    // Parameters: `int_ior` (default bk7), `ext_ior` (default air), numbers or names;
    // `specular_reflectance`, `specular_transmission` (default 1).
    static std::shared_ptr<const Bsdf> create(const Properties& props);

    Rgb f(const Vec3&, const Vec3&, TransportMode) const override { return Rgb(0.0f); }
    BsdfPdf pdf_w(const Vec3&, const Vec3&) const override { return {}; }
    std::optional<BsdfSample> sample(const Vec3& wo, float u_lobe, Vec2 u,
                                     TransportMode mode) const override;
    uint32_t lobes() const override { return kLobeDeltaReflection | kLobeDeltaTransmission; }
    std::string to_string() const override;

    float eta() const { return eta_; }

  private:
    float eta_;
    Rgb specular_reflectance_, specular_transmission_;
};

}  // namespace render
