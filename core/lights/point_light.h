#pragma once

// An isotropic point light of radiant intensity I (W/sr), Mitsuba's `point` emitter.
//
// Convention (SmallVCM's, shared by every light so that a path tracer can always compute the
// connection contribution as  radiance * f * cos_at_receiver / pdf_direct_w):
//   illuminate(): radiance = I, pdf_direct_w = d^2, cos_at_light = 1. The point is a delta
//                 in position, so the "solid-angle density" is the inverse-square falloff:
//                 radiance / pdf_direct_w = I / d^2 is the irradiance at normal incidence.
//                 pdf_emission_w = 1 / (4 pi) (the uniform direction density of emit()).
//   emit():       origin = the light position, uniform direction on the sphere,
//                 energy = I, pdf_emission_w = 1 / (4 pi), pdf_direct_a = 1 (delta).
//   radiance():   black (a point is never hit).
//   power():      4 pi I.

#include "core/lights/light.h"

namespace render {

class PointLight final : public Light {
  public:
    PointLight(const Vec3& position, const Rgb& intensity);

    bool illuminate(const Vec3& ref, Vec2 u, LightIlluminateSample& out) const override;
    bool sample_position(Vec2 u, Vec3& position) const override;
    bool emit(Vec2 u_position, Vec2 u_direction, LightEmitSample& out) const override;
    LightRadiance radiance(const Vec3& hit_point, const Vec3& hit_normal,
                           const Vec3& ray_direction) const override;
    Rgb power() const override;

    bool is_delta() const override { return true; }
    bool is_finite() const override { return true; }
    std::string to_string() const override;

    const Vec3& position() const { return position_; }

  private:
    Vec3 position_;
    Rgb intensity_;
};

}  // namespace render
