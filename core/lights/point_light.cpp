#include "core/lights/point_light.h"

#include <cmath>
#include <sstream>

#include "core/math/constants.h"
#include "core/sampling/warp.h"

namespace render {

PointLight::PointLight(const Vec3& position, const Rgb& intensity)
    : position_(position), intensity_(intensity) {}

bool PointLight::illuminate(const Vec3& ref, Vec2 /*u*/, LightIlluminateSample& out) const {
    Vec3 to_light = position_ - ref;
    float d2 = length_squared(to_light);
    // A receiver on the light itself has no direction to it.
    if (!(d2 > 0) || !std::isfinite(d2) || intensity_.is_black()) return false;
    float d = std::sqrt(d2);
    out.wi = to_light / d;
    out.distance = d;
    out.radiance = intensity_;
    out.pdf_direct_w = d2;
    out.pdf_emission_w = warp::square_to_uniform_sphere_pdf();
    out.cos_at_light = 1.0f;
    return true;
}

bool PointLight::sample_position(Vec2 /*u*/, Vec3& position) const {
    position = position_;
    return !intensity_.is_black();
}

bool PointLight::emit(Vec2 /*u_position*/, Vec2 u_direction, LightEmitSample& out) const {
    if (intensity_.is_black()) return false;
    out.origin = position_;
    out.direction = warp::square_to_uniform_sphere(u_direction);
    out.energy = intensity_;
    out.pdf_emission_w = warp::square_to_uniform_sphere_pdf();
    out.pdf_direct_a = 1.0f;
    out.cos_at_light = 1.0f;
    return true;
}

LightRadiance PointLight::radiance(const Vec3&, const Vec3&, const Vec3&) const {
    return {};
}

Rgb PointLight::power() const {
    return intensity_ * (4.0f * kPi);
}

std::string PointLight::to_string() const {
    std::ostringstream os;
    os << "PointLight[position = " << position_ << ", intensity = " << intensity_ << "]";
    return os.str();
}

}  // namespace render
