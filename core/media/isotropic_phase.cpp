#include "core/media/isotropic_phase.h"

#include "core/math/constants.h"
#include "core/sampling/warp.h"

namespace render {

float IsotropicPhase::p(const Vec3&, const Vec3&) const {
    return kInv4Pi;
}

PhaseSample IsotropicPhase::sample(const Vec3&, Vec2 u) const {
    return PhaseSample{warp::square_to_uniform_sphere(u), kInv4Pi};
}

}  // namespace render
