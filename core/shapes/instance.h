#pragma once

// Instancing (Mitsuba's shapegroup/instance, pbrt's ObjectBegin/ObjectInstance) with Embree's
// instances: a ShapeGroup's shapes live once in an Embree scene of their own; each Instance is
// an Embree instance geometry of that scene with its to_world. Memory grows with the group,
// not with the number of instances. A hit on an instance is completed by the group's shape in
// the group's space and then carried to world space (point, normals, shading frame).
// Instances cannot emit: emitters inside a group are refused by the loaders (as Mitsuba and
// pbrt-v4 do), so a light never needs to sample an instance.

#include <embree3/rtcore.h>

#include <memory>
#include <string>
#include <vector>

#include "core/base/shape.h"
#include "core/math/transform.h"

namespace render {

class ShapeGroup {
  public:
    explicit ShapeGroup(std::string name) : name_(std::move(name)) {}
    ~ShapeGroup();
    ShapeGroup(const ShapeGroup&) = delete;
    ShapeGroup& operator=(const ShapeGroup&) = delete;

    // A shape in the group's space, with its BSDF (never null) and media set.
    void add(std::unique_ptr<Shape> shape, const Bsdf* bsdf);
    bool empty() const { return shapes_.empty(); }
    const std::string& name() const { return name_; }
    const std::vector<std::unique_ptr<Shape>>& shapes() const { return shapes_; }
    Aabb bounds() const;  // in the group's space
    bool has_media() const;

    // The group's committed Embree scene on `device`, built on the first call (from
    // Scene::commit, single-threaded); every later call returns the same scene.
    RTCScene embree_scene(RTCDevice device) const;
    // The shape of a geometry id of that scene.
    const Shape* shape(unsigned geometry_id) const { return geometry_to_shape_[geometry_id]; }

  private:
    std::string name_;
    std::vector<std::unique_ptr<Shape>> shapes_;
    mutable RTCScene scene_ = nullptr;
    mutable std::vector<const Shape*> geometry_to_shape_;
};

class Instance {
  public:
    // Throws SceneError for a singular to_world.
    Instance(std::shared_ptr<const ShapeGroup> group, const Transform& to_world, std::string name);

    // Creates, commits and attaches the Embree instance geometry; returns its geometry id.
    unsigned attach(RTCDevice device, RTCScene scene) const;
    // Completes the interaction of a hit on geometry `geometry_id` of the group's scene,
    // primitive `prim_id`, barycentrics (u, v), at distance t of the world ray.
    void fill_interaction(const Ray& ray, float t, unsigned geometry_id, unsigned prim_id, float u,
                          float v, HitDetail detail, SurfaceInteraction& si) const;
    Aabb bounds() const;  // world space: the group's box, transformed
    const ShapeGroup& group() const { return *group_; }
    const Transform& to_world() const { return to_world_; }
    const std::string& name() const { return name_; }

  private:
    std::shared_ptr<const ShapeGroup> group_;
    Transform to_world_, to_object_;
    std::string name_;
};

}  // namespace render
