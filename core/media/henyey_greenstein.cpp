#include "core/media/henyey_greenstein.h"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "core/math/constants.h"
#include "core/math/frame.h"

namespace render {

HenyeyGreenstein::HenyeyGreenstein(float g) : g_(std::clamp(g, -0.999f, 0.999f)) {}

float HenyeyGreenstein::density(float cos_theta) const {
    const float denom = 1.0f + g_ * g_ - 2.0f * g_ * cos_theta;
    return kInv4Pi * (1.0f - g_ * g_) / (denom * std::sqrt(std::max(denom, 1e-12f)));
}

float HenyeyGreenstein::p(const Vec3& wo, const Vec3& wi) const {
    return density(-dot(wo, wi));
}

PhaseSample HenyeyGreenstein::sample(const Vec3& wo, Vec2 u) const {
    // Inverting the CDF of cos theta; near g = 0 the closed form loses all precision, and the
    // distribution is uniform anyway.
    float cos_theta;
    if (std::abs(g_) < 1e-3f) {
        cos_theta = 1.0f - 2.0f * u.x;
    } else {
        const float s = (1.0f - g_ * g_) / (1.0f - g_ + 2.0f * g_ * u.x);
        cos_theta = (1.0f + g_ * g_ - s * s) / (2.0f * g_);
    }
    cos_theta = std::clamp(cos_theta, -1.0f, 1.0f);
    const float sin_theta = std::sqrt(std::max(0.0f, 1.0f - cos_theta * cos_theta));
    const float phi = 2.0f * kPi * u.y;
    // theta is measured from the propagation direction -wo.
    const Frame frame = Frame::from_normal(-wo);
    const Vec3 wi =
        frame.to_world(Vec3(sin_theta * std::cos(phi), sin_theta * std::sin(phi), cos_theta));
    return PhaseSample{wi, density(cos_theta)};
}

std::string HenyeyGreenstein::to_string() const {
    std::ostringstream os;
    os << "hg(g=" << g_ << ")";
    return os.str();
}

}  // namespace render
