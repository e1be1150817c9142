#pragma once

// Makes a one-sided, non-transmissive BSDF two-sided (Mitsuba's `twosided`): a direction pair
// below the surface is mirrored to the front side and evaluated there, by the front child or,
// when two children are given, by the second one (the back side's material).

#include "core/base/properties.h"
#include "core/materials/bsdf.h"

namespace render {

class TwoSidedBsdf final : public Bsdf {
  public:
    TwoSidedBsdf(std::shared_ptr<const Bsdf> front, std::shared_ptr<const Bsdf> back);

    // Takes one or two nested BSDFs (front, then back).
    static std::shared_ptr<const Bsdf> create(const Properties& props);

    Rgb f(const Vec3& wo, const Vec3& wi, TransportMode mode) const override;
    BsdfPdf pdf_w(const Vec3& wo, const Vec3& wi) const override;
    BsdfEvaluation evaluate(const Vec3& wo, const Vec3& wi, TransportMode mode) const override;
    std::optional<BsdfSample> sample(const Vec3& wo, float u_lobe, Vec2 u,
                                     TransportMode mode) const override;
    uint32_t lobes() const override { return front_->lobes() | back_->lobes(); }
    std::string to_string() const override;

  private:
    std::shared_ptr<const Bsdf> front_, back_;
};

}  // namespace render
