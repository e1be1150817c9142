#pragma once

// Mitsuba's `null` BSDF: an invisible surface. It marks the boundary of a participating medium
// without refracting or reflecting anything (an index-matched boundary). Integrators that know
// about media step through it without counting a bounce; the others see a delta transmission
// with weight 1, which is the same light transport.

#include "core/base/properties.h"
#include "core/materials/bsdf.h"

namespace render {

class NullBsdf final : public Bsdf {
  public:
    static std::shared_ptr<const Bsdf> create(const Properties& props);

    Rgb f(const Vec3&, const Vec3&, TransportMode) const override { return Rgb(0.0f); }
    BsdfPdf pdf_w(const Vec3&, const Vec3&) const override { return {}; }
    std::optional<BsdfSample> sample(const Vec3& wo, float u_lobe, Vec2 u,
                                     TransportMode mode) const override;
    uint32_t lobes() const override { return kLobeNull; }
    std::string to_string() const override { return "null"; }
};

}  // namespace render
