#pragma once

// pbrt-v4's `diffusetransmission`: Lambertian reflection and Lambertian transmission, two-sided
// (thin leaves, curtains, lampshades). f = R / pi for directions on the same side, T / pi across.
// Samples reflection or transmission with probabilities max(R) : max(T), as pbrt-v4 does, then
// a cosine-weighted hemisphere on the chosen side. Both lobes are symmetric in wo and wi, so the
// BSDF is reciprocal and the same in both transport modes.

#include "core/base/properties.h"
#include "core/materials/bsdf.h"

namespace render {

class DiffuseTransmissionBsdf final : public Bsdf {
  public:
    DiffuseTransmissionBsdf(const Rgb& reflectance, const Rgb& transmittance);

    // Parameters (pbrt-v4's names and defaults): `reflectance` and `transmittance` (rgb, float
    // or texture, default 0.25 each), `scale` (float, default 1; multiplies both, each then
    // clamped to [0, 1] as pbrt-v4 does).
    static std::shared_ptr<const Bsdf> create(const Properties& props);

    Rgb f(const Vec3& wo, const Vec3& wi, TransportMode mode) const override;
    BsdfPdf pdf_w(const Vec3& wo, const Vec3& wi) const override;
    std::optional<BsdfSample> sample(const Vec3& wo, float u_lobe, Vec2 u,
                                     TransportMode mode) const override;
    uint32_t lobes() const override;
    std::string to_string() const override;

    const Rgb& reflectance() const { return reflectance_; }
    const Rgb& transmittance() const { return transmittance_; }

  private:
    float side_density(bool same_side, float abs_cos) const;

    Rgb reflectance_, transmittance_;
    float p_reflect_ = 0;  // probability of sampling reflection
};

}  // namespace render
