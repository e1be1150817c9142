#include "core/lights/spot_light.h"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "core/lights/point_illumination.h"
#include "core/math/constants.h"
#include "core/sampling/warp.h"

namespace render {

SpotLight::SpotLight(const Vec3& position, const Frame& frame, const Rgb& intensity, float cutoff,
                     float beam_width, std::shared_ptr<const Texture> texture)
    : position_(position),
      frame_(frame),
      intensity_(intensity),
      cutoff_(cutoff),
      beam_width_(beam_width),
      cos_cutoff_(std::cos(cutoff)),
      cos_beam_width_(std::cos(beam_width)),
      texture_(std::move(texture)) {
    if (texture_) inv_tan_cutoff_ = 1.0f / std::tan(cutoff);
}

Vec2 SpotLight::texture_uv(const Vec3& local) const {
    const float k = 0.5f * inv_tan_cutoff_ / local.z;
    return Vec2(0.5f + local.x * k, 0.5f + local.y * k);
}

Rgb SpotLight::intensity_local(const Vec3& local) const {
    const float f = falloff_local(local.z);
    if (!(f > 0)) return Rgb(0.0f);
    if (!texture_) return intensity_ * f;
    return intensity_ * texture_->eval(texture_uv(local)) * f;
}

Rgb SpotLight::intensity_toward(const Vec3& world_direction) const {
    const float len = length(world_direction);
    if (!(len > 0)) return Rgb(0.0f);
    return intensity_local(frame_.to_local(world_direction / len));
}

float SpotLight::falloff_local(float cos_theta) const {
    if (cos_theta >= cos_beam_width_) return 1.0f;
    if (!(cos_theta > cos_cutoff_)) return 0.0f;
    // Here beam_width < theta < cutoff, so the transition has a positive width.
    const float theta = std::acos(std::clamp(cos_theta, -1.0f, 1.0f));
    return std::clamp((cutoff_ - theta) / (cutoff_ - beam_width_), 0.0f, 1.0f);
}

float SpotLight::falloff(const Vec3& world_direction) const {
    const float len = length(world_direction);
    if (!(len > 0)) return 0.0f;
    return falloff_local(dot(world_direction, frame_.n) / len);
}

float SpotLight::emission_pdf_w(const Vec3& world_direction) const {
    const float len = length(world_direction);
    if (!(len > 0)) return 0.0f;
    return warp::square_to_uniform_cone_pdf(frame_.to_local(world_direction / len), cos_cutoff_);
}

bool SpotLight::illuminate(const Vec3& ref, Vec2 /*u*/, LightIlluminateSample& out) const {
    if (intensity_.is_black() || !illuminate_from_point(position_, ref, out)) return false;
    if (!texture_) {
        const float f = falloff(-out.wi);
        if (!(f > 0)) return false;  // outside the cone: no light reaches ref
        out.radiance = intensity_ * f;
    } else {
        out.radiance = intensity_toward(-out.wi);
        if (out.radiance.is_black()) return false;  // outside the cone or a black texel
    }
    out.pdf_emission_w = emission_pdf_w(-out.wi);
    return true;
}

bool SpotLight::sample_position(Vec2 /*u*/, Vec3& position) const {
    position = position_;
    return !intensity_.is_black();
}

bool SpotLight::emit(Vec2 /*u_position*/, Vec2 u_direction, LightEmitSample& out) const {
    if (intensity_.is_black()) return false;
    const Vec3 local = warp::square_to_uniform_cone(u_direction, cos_cutoff_);
    const float f = falloff_local(local.z);
    if (!(f > 0)) return false;
    out.origin = position_;
    out.direction = normalize(frame_.to_world(local));
    out.energy = texture_ ? intensity_local(local) : intensity_ * f;
    if (texture_ && out.energy.is_black()) return false;  // a black texel
    out.pdf_emission_w = warp::square_to_uniform_cone_pdf(local, cos_cutoff_);
    out.pdf_direct_a = 1.0f;
    out.cos_at_light = 1.0f;
    return true;
}

LightRadiance SpotLight::radiance(const Vec3&, const Vec3&, const Vec3&) const {
    return {};
}

Rgb SpotLight::power() const {
    const double width = double(cutoff_) - double(beam_width_);
    const double solid_angle =
        width > 1e-6
            ? 2.0 * M_PI *
                  (1.0 - (std::sin(double(cutoff_)) - std::sin(double(beam_width_))) / width)
            : 2.0 * M_PI * (1.0 - std::cos(double(cutoff_)));
    return intensity_ * (texture_ ? texture_->mean() : Rgb(1.0f)) * float(solid_angle);
}

std::string SpotLight::to_string() const {
    std::ostringstream os;
    os << "SpotLight[position = " << position_ << ", axis = " << frame_.n
       << ", intensity = " << intensity_ << ", cutoff_angle = " << cutoff_ * 180.0f / kPi
       << ", beam_width = " << beam_width_ * 180.0f / kPi;
    if (texture_) os << ", texture = " << texture_->to_string();
    os << "]";
    return os.str();
}

}  // namespace render
