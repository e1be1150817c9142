#pragma once

#include <string>

#include "core/shapes/user_geometry.h"

namespace render {

// Analytic sphere (Embree user geometry; intersected in double precision, never tessellated).
// Normals point outward unless flip_normals is set. uv is Mitsuba's: with the hit's direction
// from the centre in object space (`axes`: the world directions of the object's x, y, z axes),
// u = phi / 2pi (phi = atan2(y, x) in [0, 2pi)) and v = theta / pi (theta = acos(z)).
class Sphere final : public AnalyticShape {
  public:
    Sphere(const Vec3& center, float radius, bool flip_normals, std::string name,
           const Frame& axes = Frame());

    std::optional<double> nearest_hit(const float org[3], const float dir[3], float t_min,
                                      float t_max) const override;
    void fill_interaction(const Ray& ray, float t, unsigned prim_id, float u, float v,
                          HitDetail detail, SurfaceInteraction& si) const override;
    Aabb bounds() const override;
    float surface_area() const override;
    ShapeSample sample_area(Vec2 u) const override;
    std::string to_string() const override;
    bool has_uv_lookup() const override { return true; }
    Vec2 uv_at(const Vec3& p) const override;

    Vec3 center() const { return center_; }
    float radius() const { return radius_; }

  private:
    // uv of the unit direction d from the centre.
    Vec2 uv_of_direction(const Vec3& d) const;

    Vec3 center_;
    float radius_;
    bool flip_normals_;
    std::string name_;
    Frame axes_;
};

}  // namespace render
