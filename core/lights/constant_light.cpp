#include "core/lights/constant_light.h"

#include <sstream>

#include "core/lights/scene_disk.h"
#include "core/math/constants.h"
#include "core/sampling/warp.h"

namespace render {

ConstantLight::ConstantLight(const Rgb& radiance) : radiance_(radiance) {}

bool ConstantLight::illuminate(const Vec3& /*ref*/, Vec2 u, LightIlluminateSample& out) const {
    if (radiance_.is_black()) return false;
    float pdf_w = warp::square_to_uniform_sphere_pdf();
    out.wi = warp::square_to_uniform_sphere(u);
    out.distance = kInfinity;
    out.radiance = radiance_;
    out.pdf_direct_w = pdf_w;
    out.pdf_emission_w = pdf_w * scene_disk::pdf_area(scene_sphere_);
    out.cos_at_light = 1.0f;
    return true;
}

bool ConstantLight::emit(Vec2 u_position, Vec2 u_direction, LightEmitSample& out) const {
    if (radiance_.is_black()) return false;
    // Sample the direction toward the background exactly as illuminate() does, then reverse
    // it: the two techniques then report the same densities for the same path.
    Vec3 wi = warp::square_to_uniform_sphere(u_direction);
    float pdf_w = warp::square_to_uniform_sphere_pdf();
    out.direction = -wi;
    out.origin = scene_disk::sample_origin(scene_sphere_, out.direction, u_position);
    out.energy = radiance_;
    out.pdf_emission_w = pdf_w * scene_disk::pdf_area(scene_sphere_);
    out.pdf_direct_a = pdf_w;
    out.cos_at_light = 1.0f;
    return true;
}

LightRadiance ConstantLight::radiance(const Vec3&, const Vec3&, const Vec3&) const {
    LightRadiance r;
    r.radiance = radiance_;
    r.pdf_direct_a = warp::square_to_uniform_sphere_pdf();
    r.pdf_emission_w = r.pdf_direct_a * scene_disk::pdf_area(scene_sphere_);
    return r;
}

Rgb ConstantLight::power() const {
    return radiance_ * (4.0f * kPi * scene_disk::area(scene_sphere_));
}

std::string ConstantLight::to_string() const {
    std::ostringstream os;
    os << "ConstantLight[radiance = " << radiance_ << "]";
    return os.str();
}

}  // namespace render
