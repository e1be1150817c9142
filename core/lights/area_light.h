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
//                 radiance_at() gives the same for a hit, from its primitive and parameters
//                 (SurfaceInteraction::prim_id, prim_uv); radiance() from the point alone
//                 first finds them (Shape::locate, or the textured mesh's locator).
//   power():      pi * area * Le.
// A zero-area shape emits nothing (every sampling routine fails, pdfs are 0).
//
// A textured radiance (Mitsuba's `radiance` texture) is looked up at the uv of the emitting
// point: the sampled one (illuminate, emit) or the hit one (radiance(), through a point
// lookup). On a triangle mesh of any size, points are sampled by radiance x area and the same
// density is found back from a hit (textured_mesh_emission.h): pdf_area above is then that
// density, in every routine alike. On a sphere or disk they are sampled uniformly by area and
// uv comes from the shape's uv_at. power() uses the texture's mean.
//
// Shapes that do not sample uniformly by area (bilinear patches, core/shapes/bilinear_patch.h)
// say so through Shape::pdf_area: pdf_area above is then their density at the point, sampled
// or hit.

#include "core/base/shape.h"
#include "core/lights/light.h"
#include "core/lights/textured_mesh_emission.h"
#include "core/textures/texture_param.h"

namespace render {

class AreaLight final : public Light {
  public:
    // `shape` must outlive the light (the scene owns both).
    AreaLight(const Shape* shape, const Rgb& radiance);
    // A textured radiance needs a triangle mesh or shape->has_uv_lookup() (throws
    // std::invalid_argument). `importance_sampled` false samples a mesh uniformly by area
    // too (tests compare the two).
    AreaLight(const Shape* shape, const RgbParam& radiance, bool importance_sampled = true);

    bool illuminate(const Vec3& ref, Vec2 u, LightIlluminateSample& out) const override;
    bool sample_position(Vec2 u, Vec3& position) const override;
    bool emit(Vec2 u_position, Vec2 u_direction, LightEmitSample& out) const override;
    LightRadiance radiance(const Vec3& hit_point, const Vec3& hit_normal,
                           const Vec3& ray_direction) const override;
    LightRadiance radiance_at(const SurfaceInteraction& hit,
                              const Vec3& ray_direction) const override;
    Rgb power() const override;

    bool is_delta() const override { return false; }
    bool is_finite() const override { return true; }
    std::string to_string() const override;

    const Shape* shape() const { return shape_; }
    // The textured mesh's sampler, or null (uniform by area).
    const TexturedMeshEmission* textured_mesh() const {
        return uniform_mesh_ ? nullptr : mesh_emission_.get();
    }

  private:
    // A point by area (uniformly, or by radiance x area on a textured mesh).
    ShapeSample sample_point(Vec2 u) const {
        return mesh_emission_ && !uniform_mesh_ ? mesh_emission_->sample(u)
                                                : shape_->sample_area(u);
    }

    // Le at a sampled or hit point.
    Rgb radiance_at(Vec2 uv) const {
        return textured_ ? radiance_param_.texture->eval(uv) : radiance_;
    }
    // radiance() at the hit (prim_id, prim_uv) at point p, cos_light > 0.
    LightRadiance radiance_of_hit(unsigned prim_id, Vec2 prim_uv, const Vec3& p,
                                  float cos_light) const;

    const Shape* shape_;
    Rgb radiance_;  // the constant, or the texture's mean
    RgbParam radiance_param_;
    bool textured_ = false;
    std::unique_ptr<TexturedMeshEmission> mesh_emission_;  // textured meshes: the point lookup
    bool uniform_mesh_ = false;  // ... but sampled uniformly by area all the same
    float area_;
    float inv_area_;  // 0 for a zero-area shape
};

}  // namespace render
