#pragma once

// Phase functions: the angular distribution of scattering inside a medium. Directions follow
// the BSDF convention (core/materials/bsdf.h): both point away from the scattering point, `wo`
// toward where the path came from and `wi` toward where it continues, so forward scattering
// means wi = -wo. Every phase function here is normalised over the sphere and sampled exactly,
// so its value equals its density and a sample's weight is 1; that is also why it is reciprocal
// (p(wo, wi) = p(wi, wo)) and the same in both transport modes.

#include <optional>
#include <string>

#include "core/math/vec.h"

namespace render {

struct PhaseSample {
    Vec3 wi;
    float pdf_w = 0;  // solid angle; equals the phase function's value
};

class PhaseFunction {
  public:
    virtual ~PhaseFunction() = default;
    // p(wo, wi), per steradian.
    virtual float p(const Vec3& wo, const Vec3& wi) const = 0;
    virtual PhaseSample sample(const Vec3& wo, Vec2 u) const = 0;
    virtual std::string to_string() const = 0;
};

}  // namespace render
