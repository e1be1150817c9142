#pragma once

#include "core/media/phase_function.h"

namespace render {

// Scatters uniformly over the sphere: p = 1 / (4 pi).
class IsotropicPhase final : public PhaseFunction {
  public:
    float p(const Vec3& wo, const Vec3& wi) const override;
    PhaseSample sample(const Vec3& wo, Vec2 u) const override;
    std::string to_string() const override { return "isotropic"; }
};

}  // namespace render
