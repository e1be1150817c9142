#pragma once

// A thin dielectric slab (Mitsuba's `thindielectric`): a pane of glass with two parallel
// interfaces so close together that light leaves where it entered. Reflection is delta
// (mirror) and transmission is delta *straight through* (wi = -wo: the two refractions cancel,
// no radiance scaling, eta 1). Summing the inter-reflections inside the slab gives
//     R' = R + T^2 R / (1 - R^2),  T = 1 - R,  transmission 1 - R',
// with R the single-interface Fresnel reflectance at |cos theta|. One lobe is chosen with
// probability R' (resp. 1 - R'), so the sample weight is the specular_reflectance or
// specular_transmission tint. Both sides behave alike.

#include "core/base/properties.h"
#include "core/materials/bsdf.h"

namespace render {

class ThinDielectricBsdf final : public Bsdf {
  public:
    // eta = n_inside / n_outside of the slab's material.
    ThinDielectricBsdf(float eta, const Rgb& specular_reflectance,
                       const Rgb& specular_transmission);

    // Parameters: `int_ior` (default bk7), `ext_ior` (default air), numbers or names;
    // `specular_reflectance`, `specular_transmission` (default 1).
    static std::shared_ptr<const Bsdf> create(const Properties& props);

    // The slab's reflectance R' for a direction of cosine cos_theta (either side).
    float slab_reflectance(float cos_theta) const;

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
