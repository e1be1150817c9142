#pragma once

// Smooth conductor (Mitsuba's `conductor`): a delta mirror whose reflectance is the exact
// Fresnel term of a complex IOR, times `specular_reflectance`. Without an IOR ("none") it is a
// perfect mirror of reflectance `specular_reflectance`. One-sided.

#include "core/base/properties.h"
#include "core/materials/bsdf.h"
#include "core/materials/ior.h"

namespace render {

class ConductorBsdf final : public Bsdf {
  public:
    // `ior` absent: no Fresnel term (reflectance 1).
    ConductorBsdf(std::optional<ConductorIor> ior, const Rgb& specular_reflectance);

    // Parameters: `eta` and `k` (rgb) or `material` (none, Au, Ag, Cu, Al, Cr; default none),
    // `specular_reflectance` (default 1).
    static std::shared_ptr<const Bsdf> create(const Properties& props);

    Rgb f(const Vec3&, const Vec3&, TransportMode) const override { return Rgb(0.0f); }
    BsdfPdf pdf_w(const Vec3&, const Vec3&) const override { return {}; }
    std::optional<BsdfSample> sample(const Vec3& wo, float u_lobe, Vec2 u,
                                     TransportMode mode) const override;
    uint32_t lobes() const override { return kLobeDeltaReflection; }
    std::string to_string() const override;

    // Reflectance for a direction with cosine cos_theta >= 0 to the normal.
    Rgb reflectance(float cos_theta) const;

  private:
    std::optional<ConductorIor> ior_;
    Rgb specular_reflectance_;
};

}  // namespace render
