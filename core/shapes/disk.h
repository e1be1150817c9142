#pragma once

#include <string>

#include "core/math/transform.h"
#include "core/shapes/user_geometry.h"

namespace render {

// Analytic disk: the unit disk at z = 0 in object space with normal +z, mapped by to_world
// (Mitsuba's `disk`). Embree user geometry.
class Disk final : public AnalyticShape {
  public:
    // Throws SceneError if to_world is singular.
    Disk(const Transform& to_world, bool flip_normals, std::string name);

    std::optional<double> nearest_hit(const float org[3], const float dir[3], float t_min,
                                      float t_max) const override;
    void fill_interaction(const Ray& ray, float t, unsigned prim_id, float u, float v,
                          HitDetail detail, SurfaceInteraction& si) const override;
    Aabb bounds() const override;
    float surface_area() const override { return area_; }
    ShapeSample sample_area(Vec2 u) const override;
    std::string to_string() const override;

    bool has_uv_lookup() const override { return true; }
    Vec2 uv_at(const Vec3& p) const override;

  private:
    // uv of object-space point (x, y) of the unit disk.
    static Vec2 uv_of_local(float x, float y);

    Transform to_world_;
    Transform to_object_;
    Vec3 center_, normal_;
    float area_;
    bool flip_normals_;
    std::string name_;
};

}  // namespace render
