#pragma once

// A spot light (Mitsuba's `spot` emitter): a point light at the origin of `to_world` shining
// along its local +z, with radiant intensity I times a falloff that depends only on the angle
// theta from the axis:
//   falloff(theta) = 1                                       for theta <= beam_width,
//                    (cutoff - theta) / (cutoff - beam_width) for beam_width < theta < cutoff,
//                    0                                       for theta >= cutoff
// (Mitsuba's profile: linear in the angle; cutoff_angle defaults to 20 degrees and beam_width
// to 3/4 of it).
//
// An optional projected `texture` (Mitsuba 3's) multiplies the intensity by its value at
// uv = (1/2 + x / (2 z tan cutoff), 1/2 + y / (2 z tan cutoff)) for the local direction
// (x, y, z): the image spans the cone's square of half-angle cutoff. Directions are still
// sampled uniformly in the cone (the densities are unchanged); power() uses the texture's mean.
//
// Conventions as PointLight (point_light.h):
//   illuminate(): radiance = I falloff, pdf_direct_w = d^2, cos_at_light = 1,
//                 pdf_emission_w = the cone density of emit() for that direction.
//   emit():       uniform direction in the cone of half-angle cutoff, pdf_emission_w =
//                 1 / (2 pi (1 - cos cutoff)), energy = I falloff, pdf_direct_a = 1 (delta).
//   radiance():   black (a point is never hit).
//   power():      I times the integral of the falloff over the sphere,
//                 2 pi I [1 - (sin cutoff - sin beam) / (cutoff - beam)]
//                 (2 pi I (1 - cos cutoff) when beam == cutoff).

#include <memory>

#include "core/lights/light.h"
#include "core/math/frame.h"
#include "core/textures/texture.h"

namespace render {

class SpotLight final : public Light {
  public:
    // `frame.n` is the axis; angles in radians with 0 <= beam_width <= cutoff <= pi,
    // cutoff > 0.
    // `texture` (may be null) needs cutoff < pi / 2.
    SpotLight(const Vec3& position, const Frame& frame, const Rgb& intensity, float cutoff,
              float beam_width, std::shared_ptr<const Texture> texture = nullptr);

    bool illuminate(const Vec3& ref, Vec2 u, LightIlluminateSample& out) const override;
    bool sample_position(Vec2 u, Vec3& position) const override;
    bool emit(Vec2 u_position, Vec2 u_direction, LightEmitSample& out) const override;
    LightRadiance radiance(const Vec3& hit_point, const Vec3& hit_normal,
                           const Vec3& ray_direction) const override;
    Rgb power() const override;

    bool is_delta() const override { return true; }
    bool is_finite() const override { return true; }
    std::string to_string() const override;

    // The falloff for a world direction leaving the light (need not be unit length).
    float falloff(const Vec3& world_direction) const;
    // The intensity toward a world direction leaving the light: I falloff texture.
    Rgb intensity_toward(const Vec3& world_direction) const;
    // The projected texture's uv of a local direction with z > 0.
    Vec2 texture_uv(const Vec3& local) const;
    // emit()'s solid-angle density of a world direction leaving the light.
    float emission_pdf_w(const Vec3& world_direction) const;

    const Vec3& position() const { return position_; }

  private:
    float falloff_local(float cos_theta) const;
    // I falloff texture for a unit local direction.
    Rgb intensity_local(const Vec3& local) const;

    Vec3 position_;
    Frame frame_;
    Rgb intensity_;
    float cutoff_, beam_width_;
    float cos_cutoff_, cos_beam_width_;
    std::shared_ptr<const Texture> texture_;
    float inv_tan_cutoff_ = 0;  // with a texture
};

}  // namespace render
