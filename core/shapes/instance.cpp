#include "core/shapes/instance.h"

#include <cmath>

#include "core/base/error.h"

namespace render {

ShapeGroup::~ShapeGroup() {
    if (scene_) rtcReleaseScene(scene_);
}

void ShapeGroup::add(std::unique_ptr<Shape> shape, const Bsdf* bsdf) {
    shape->bsdf = bsdf;
    shapes_.push_back(std::move(shape));
}

Aabb ShapeGroup::bounds() const {
    Aabb box;
    for (const auto& shape : shapes_) box.expand(shape->bounds());
    return box;
}

bool ShapeGroup::has_media() const {
    for (const auto& shape : shapes_)
        if (shape->interior || shape->exterior) return true;
    return false;
}

RTCScene ShapeGroup::embree_scene(RTCDevice device) const {
    if (scene_) return scene_;
    scene_ = rtcNewScene(device);
    rtcSetSceneFlags(scene_, RTC_SCENE_FLAG_ROBUST);
    rtcSetSceneBuildQuality(scene_, RTC_BUILD_QUALITY_HIGH);
    for (const auto& shape : shapes_) {
        const unsigned id = shape->attach(device, scene_);
        if (id >= geometry_to_shape_.size()) geometry_to_shape_.resize(id + 1, nullptr);
        geometry_to_shape_[id] = shape.get();
    }
    rtcCommitScene(scene_);
    return scene_;
}

Instance::Instance(std::shared_ptr<const ShapeGroup> group, const Transform& to_world,
                   std::string name)
    : group_(std::move(group)),
      to_world_(to_world),
      to_object_(to_world.inverse()),
      name_(std::move(name)) {
    if (to_world.is_singular()) throw SceneError(name_ + ": to_world transform is singular");
}

unsigned Instance::attach(RTCDevice device, RTCScene scene) const {
    RTCGeometry geometry = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_INSTANCE);
    rtcSetGeometryInstancedScene(geometry, group_->embree_scene(device));
    rtcSetGeometryTimeStepCount(geometry, 1);
    // Embree's 3x4 column-major layout: the three axis columns, then the translation.
    float columns[12];
    const Transform::Matrix& m = to_world_.matrix();
    for (int c = 0; c < 4; ++c)
        for (int r = 0; r < 3; ++r) columns[3 * c + r] = float(m[size_t(r)][size_t(c)]);
    rtcSetGeometryTransform(geometry, 0, RTC_FORMAT_FLOAT3X4_COLUMN_MAJOR, columns);
    rtcCommitGeometry(geometry);
    const unsigned id = rtcAttachGeometry(scene, geometry);
    rtcReleaseGeometry(geometry);
    return id;
}

void Instance::fill_interaction(const Ray& ray, float t, unsigned geometry_id, unsigned prim_id,
                                float u, float v, HitDetail detail, SurfaceInteraction& si) const {
    // Embree reports t along the ray carried into the group's space without normalising its
    // direction, so the same t locates the hit there.
    const Ray local(to_object_.apply_point(ray.origin), to_object_.apply_vector(ray.direction),
                    ray.t_min, ray.t_max);
    group_->shape(geometry_id)->fill_interaction(local, t, prim_id, u, v, detail, si);
    si.p = to_world_.apply_point(si.p);
    si.t = t;
    // The inverse transpose keeps a normal on the side it faced (also under a mirroring
    // to_world), so a group's outside stays the outside.
    si.geometric_normal = normalize(to_world_.apply_normal(si.geometric_normal));
    si.shading = Frame::from_normal(normalize(to_world_.apply_normal(si.shading.n)));
    si.dpdu = to_world_.apply_vector(si.dpdu);
    si.dpdv = to_world_.apply_vector(si.dpdv);
}

Aabb Instance::bounds() const {
    const Aabb b = group_->bounds();
    Aabb box;
    if (b.empty()) return box;
    for (int corner = 0; corner < 8; ++corner)
        box.expand(
            to_world_.apply_point(Vec3(corner & 1 ? b.hi.x : b.lo.x, corner & 2 ? b.hi.y : b.lo.y,
                                       corner & 4 ? b.hi.z : b.lo.z)));
    return box;
}

}  // namespace render
