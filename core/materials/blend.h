#pragma once

// Mitsuba's `blendbsdf` and `mask`: the linear blend (1 - w) f_0 + w f_1 of two BSDFs.
// Sampling picks the second BSDF with probability w and the first otherwise (the lobe number is
// reused, rescaled), then reports the blend's own density and weight: for a non-delta sample
// the mixture density (1 - w) p_0 + w p_1 and f_blend |cos| / that density; for a delta lobe of
// one child its discrete probability times that child's selection probability.
//
// `mask` is the blend of the `null` BSDF (w = 0 side) and the nested BSDF with w = opacity: a
// surface that a path passes straight through with probability 1 - opacity, the way
// index-matched media boundaries are crossed (a delta `kLobeNull` transmission of weight 1).
// Shadow rays and bidirectional connections see it as an opaque surface (like any surface with
// a delta transmission), so light through the holes is carried by sampled pass-throughs only.

#include <memory>

#include "core/base/properties.h"
#include "core/materials/bsdf.h"
#include "core/textures/texture_param.h"

namespace render {

class BlendBsdf final : public Bsdf {
  public:
    // `weight` in [0, 1] is the share of `second`. `mask` only changes the description.
    BlendBsdf(std::shared_ptr<const Bsdf> first, std::shared_ptr<const Bsdf> second, float weight,
              bool mask = false);

    // blendbsdf: `weight` (float or texture, 0.5; a colour texture's luminance, clamped to
    // [0, 1] as Mitsuba) and exactly two nested BSDFs.
    static std::shared_ptr<const Bsdf> create(const Properties& props);
    // mask: `opacity` (float or texture, 0.5, clamped to [0, 1]) and one nested BSDF.
    static std::shared_ptr<const Bsdf> create_mask(const Properties& props);

    float weight() const { return weight_; }

    Rgb f(const Vec3& wo, const Vec3& wi, TransportMode mode) const override;
    BsdfPdf pdf_w(const Vec3& wo, const Vec3& wi) const override;
    std::optional<BsdfSample> sample(const Vec3& wo, float u_lobe, Vec2 u,
                                     TransportMode mode) const override;
    uint32_t lobes() const override { return lobes_; }
    std::string to_string() const override;

  private:
    std::shared_ptr<const Bsdf> first_, second_;
    float weight_;
    bool mask_;
    uint32_t lobes_;
};

}  // namespace render
