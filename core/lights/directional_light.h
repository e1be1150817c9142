#pragma once

// A distant light: parallel rays travelling along `direction` with irradiance E (W/m^2) on a
// surface perpendicular to them. Mitsuba's `directional` emitter (`direction`, or `to_world`
// rotating the local +z axis; `irradiance`).
//
// Conventions (SmallVCM's):
//   illuminate(): wi = -direction, distance = infinity, radiance = E, pdf_direct_w = 1
//                 (delta direction), cos_at_light = 1,
//                 pdf_emission_w = 1 / (pi R^2) (the scene disk, see scene_disk.h).
//   emit():       origin uniform on the scene disk perpendicular to `direction` (starting R
//                 behind the scene centre), direction = `direction`, energy = E,
//                 pdf_emission_w = 1 / (pi R^2), pdf_direct_a = 1.
//   radiance():   black (a delta direction is never hit by a ray).
//   power():      pi R^2 E, the power crossing the scene disk (needs preprocess()).

#include "core/lights/light.h"

namespace render {

class DirectionalLight final : public Light {
  public:
    // `direction` need not be unit; it must be non-zero and finite (the factory checks).
    DirectionalLight(const Vec3& direction, const Rgb& irradiance);

    bool illuminate(const Vec3& ref, Vec2 u, LightIlluminateSample& out) const override;
    bool emit(Vec2 u_position, Vec2 u_direction, LightEmitSample& out) const override;
    LightRadiance radiance(const Vec3& hit_point, const Vec3& hit_normal,
                           const Vec3& ray_direction) const override;
    Rgb power() const override;

    bool is_delta() const override { return true; }
    bool is_finite() const override { return false; }
    std::string to_string() const override;

    const Vec3& direction() const { return direction_; }

  private:
    Vec3 direction_;  // unit, the direction light travels
    Rgb irradiance_;
};

}  // namespace render
