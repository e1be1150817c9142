#pragma once

// A uniform infinite background of radiance Le (Mitsuba's `constant` emitter), seen by every
// ray that leaves the scene. SmallVCM's background light.
//
// Conventions (directions are unit; R is the scene radius, see scene_disk.h):
//   illuminate(): wi uniform on the whole sphere (as Mitsuba 3), distance = infinity,
//                 radiance = Le, pdf_direct_w = 1 / (4 pi),
//                 pdf_emission_w = 1 / (4 pi) * 1 / (pi R^2)  (direction times disk density).
//   emit():       wi uniform on the sphere; the ray travels inward along d = -wi from the
//                 scene disk perpendicular to d; energy = Le, pdf_emission_w as above,
//                 pdf_direct_a = 1 / (4 pi) (a solid-angle density, see light.h).
//   radiance():   for a ray escaping along `ray_direction`: Le, pdf_direct_a = 1 / (4 pi),
//                 pdf_emission_w as above.
//   power():      4 pi * pi R^2 * Le: the power that crosses the scene disk over all
//                 directions, i.e. the integral of energy / pdf over emit()'s samples
//                 (needs preprocess()).

#include "core/lights/light.h"

namespace render {

class ConstantLight final : public Light {
  public:
    explicit ConstantLight(const Rgb& radiance);

    bool illuminate(const Vec3& ref, Vec2 u, LightIlluminateSample& out) const override;
    bool emit(Vec2 u_position, Vec2 u_direction, LightEmitSample& out) const override;
    LightRadiance radiance(const Vec3& hit_point, const Vec3& hit_normal,
                           const Vec3& ray_direction) const override;
    Rgb power() const override;

    bool is_delta() const override { return false; }
    bool is_finite() const override { return false; }
    bool is_infinite_background() const override { return true; }
    std::string to_string() const override;

  private:
    Rgb radiance_;
};

}  // namespace render
