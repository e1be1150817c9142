#pragma once

// A diffuse area light on any shape (Mitsuba's `area` emitter nested in a shape): constant
// radiance Le leaving the side the shape's normal points to, black from behind (one-sided).
//
// Conventions (SmallVCM's), with pdf_area = 1 / surface area (uniform area sampling) and
// cos = cosine between the light's normal and the leaving direction:
//   illuminate(): point by area; pdf_direct_w = pdf_area * d^2 / cos, pdf_emission_w =
//                 pdf_area * cos / pi; fails for points seen from behind (cos <= 0).
//   emit():       point by area, direction cosine-weighted about the normal;
//                 energy = Le * cos, pdf_emission_w = pdf_area * cos / pi,
//                 pdf_direct_a = pdf_area.
//   radiance():   Le if dot(hit_normal, -ray_direction) > 0 (else black, pdfs 0), with
//                 pdf_direct_a = pdf_area and pdf_emission_w = pdf_area * cos / pi.
//   power():      pi * area * Le.
// A zero-area shape emits nothing (every sampling routine fails, pdfs are 0).

#include "core/base/shape.h"
#include "core/lights/light.h"

namespace render {

class AreaLight final : public Light {
  public:
    // `shape` must outlive the light (the scene owns both).
    AreaLight(const Shape* shape, const Rgb& radiance);

    bool illuminate(const Vec3& ref, Vec2 u, LightIlluminateSample& out) const override;
    bool sample_position(Vec2 u, Vec3& position) const override;
    bool emit(Vec2 u_position, Vec2 u_direction, LightEmitSample& out) const override;
    LightRadiance radiance(const Vec3& hit_point, const Vec3& hit_normal,
                           const Vec3& ray_direction) const override;
    Rgb power() const override;

    bool is_delta() const override { return false; }
    bool is_finite() const override { return true; }
    std::string to_string() const override;

    const Shape* shape() const { return shape_; }

  private:
    const Shape* shape_;
    Rgb radiance_;
    float area_;
    float inv_area_;  // 0 for a zero-area shape
};

}  // namespace render
