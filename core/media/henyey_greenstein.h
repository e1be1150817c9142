#pragma once

#include "core/media/phase_function.h"

namespace render {

// Henyey-Greenstein (1941): p(theta) = (1 - g^2) / (4 pi (1 + g^2 - 2 g cos theta)^(3/2)), where
// theta is the angle between the propagation directions before and after scattering
// (cos theta = dot(-wo, wi)); g = mean cosine, > 0 forward, < 0 backward scattering.
class HenyeyGreenstein final : public PhaseFunction {
  public:
    // g is clamped to (-0.999, 0.999): |g| -> 1 is a delta lobe the density cannot represent.
    explicit HenyeyGreenstein(float g);
    float p(const Vec3& wo, const Vec3& wi) const override;
    PhaseSample sample(const Vec3& wo, Vec2 u) const override;
    std::string to_string() const override;
    float g() const { return g_; }

  private:
    float density(float cos_theta) const;
    float g_;
};

}  // namespace render
