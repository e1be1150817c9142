#include "core/lights/directional_light.h"

#include <sstream>

#include "core/lights/scene_disk.h"
#include "core/math/constants.h"

namespace render {

DirectionalLight::DirectionalLight(const Vec3& direction, const Rgb& irradiance)
    : direction_(normalize(direction)), irradiance_(irradiance) {}

bool DirectionalLight::illuminate(const Vec3& /*ref*/, Vec2 /*u*/,
                                  LightIlluminateSample& out) const {
    if (irradiance_.is_black()) return false;
    out.wi = -direction_;
    out.distance = kInfinity;
    out.radiance = irradiance_;
    out.pdf_direct_w = 1.0f;
    out.pdf_emission_w = scene_disk::pdf_area(scene_sphere_);
    out.cos_at_light = 1.0f;
    return true;
}

bool DirectionalLight::emit(Vec2 u_position, Vec2 /*u_direction*/, LightEmitSample& out) const {
    if (irradiance_.is_black()) return false;
    out.origin = scene_disk::sample_origin(scene_sphere_, direction_, u_position);
    out.direction = direction_;
    out.energy = irradiance_;
    out.pdf_emission_w = scene_disk::pdf_area(scene_sphere_);
    out.pdf_direct_a = 1.0f;
    out.cos_at_light = 1.0f;
    return true;
}

LightRadiance DirectionalLight::radiance(const Vec3&, const Vec3&, const Vec3&) const {
    return {};
}

Rgb DirectionalLight::power() const {
    return irradiance_ * scene_disk::area(scene_sphere_);
}

std::string DirectionalLight::to_string() const {
    std::ostringstream os;
    os << "DirectionalLight[direction = " << direction_ << ", irradiance = " << irradiance_ << "]";
    return os.str();
}

}  // namespace render
