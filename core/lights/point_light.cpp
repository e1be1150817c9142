#include "core/lights/point_light.h"

#include <cmath>
#include <sstream>

#include "core/lights/point_illumination.h"
#include "core/math/constants.h"
#include "core/sampling/warp.h"

namespace render {

PointLight::PointLight(const Vec3& position, const Rgb& intensity)
    : position_(position), intensity_(intensity) {}

bool PointLight::illuminate(const Vec3& ref, Vec2 /*u*/, LightIlluminateSample& out) const {
    if (intensity_.is_black() || !illuminate_from_point(position_, ref, out)) return false;
    out.radiance = intensity_;
    out.pdf_emission_w = warp::square_to_uniform_sphere_pdf();
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
