#include "core/scene/scene.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "core/base/error.h"
#include "core/base/memory_budget.h"
#include "core/base/properties.h"
#include "core/materials/bsdf_factory.h"
#include "core/media/medium.h"
#include "core/scene/embree_ray.h"
#include "core/scene/invalid_ray_tally.h"
#include "core/scene/volume_emitter.h"
#include "core/shapes/instance.h"
#include "core/shapes/triangle_mesh_hit.h"
#include "core/shapes/user_geometry.h"

namespace render {
namespace {

void embree_error(void*, RTCError code, const char* message) {
    std::fprintf(stderr, "embree error %d: %s\n", int(code), message ? message : "");
}

float max_abs_component(const Vec3& p) {
    return std::max(std::abs(p.x), std::max(std::abs(p.y), std::abs(p.z)));
}

}  // namespace

Scene::Scene() {
    device_ = rtcNewDevice(nullptr);
    if (!device_) throw SceneError("could not create an Embree device");
    rtcSetDeviceErrorFunction(device_, embree_error, nullptr);
    rtc_scene_ = rtcNewScene(device_);
    rtcSetSceneFlags(rtc_scene_, RTC_SCENE_FLAG_ROBUST);
    rtcSetSceneBuildQuality(rtc_scene_, RTC_BUILD_QUALITY_HIGH);
    // Shadow rays go through a second BVH over the same geometries (but the directly tested
    // analytic shapes, scene.h), built without ROBUST: its traversal takes about a third less time,
    // and an occlusion test only answers yes or no, which the two BVHs give differently only for a
    // ray within float rounding of a triangle's edge or a node's box
    // (docs/results/performance-notes.md, "Shadow rays through their own BVH"). MEDIUM quality:
    // HIGH's spatial splits cost build time the shadow rays do not win back.
    occlusion_scene_ = rtcNewScene(device_);
    rtcSetSceneFlags(occlusion_scene_, RTC_SCENE_FLAG_NONE);
    rtcSetSceneBuildQuality(occlusion_scene_, RTC_BUILD_QUALITY_MEDIUM);
}

Scene::~Scene() {
    instances_.clear();  // their groups' Embree scenes go before the device
    if (occlusion_scene_) rtcReleaseScene(occlusion_scene_);
    if (rtc_scene_) rtcReleaseScene(rtc_scene_);
    if (device_) rtcReleaseDevice(device_);
}

const Bsdf* Scene::add_bsdf(std::shared_ptr<const Bsdf> bsdf) {
    bsdfs_.push_back(std::move(bsdf));
    return bsdfs_.back().get();
}

Shape* Scene::add_shape(std::unique_ptr<Shape> shape, const Bsdf* bsdf) {
    if (!bsdf) {
        // A shape without a BSDF absorbs everything: emitters in the reference scenes are black.
        Properties black("bsdf", "diffuse", SourceLocation{"<default>", 0});
        black.set("reflectance", Rgb(0.0f), SourceLocation{"<default>", 0});
        bsdf = add_bsdf(make_bsdf(black));
    }
    shape->bsdf = bsdf;
    shapes_.push_back(std::move(shape));
    return shapes_.back().get();
}

void Scene::add_instance(std::unique_ptr<Instance> instance) {
    instances_.push_back(std::move(instance));
}

const Medium* Scene::add_medium(std::shared_ptr<const Medium> medium, std::string name) {
    media_.push_back(std::move(medium));
    medium_names_.push_back(std::move(name));
    return media_.back().get();
}

const Light* Scene::add_light(std::unique_ptr<Light> light) {
    lights_.push_back(std::move(light));
    return lights_.back().get();
}

void Scene::commit() {
    if (committed_) return;
    size_t analytic_shapes = 0, triangles = 0;
    for (const auto& shape : shapes_) {
        analytic_shapes += dynamic_cast<const AnalyticShape*>(shape.get()) ? 1 : 0;
        if (const auto* mesh = dynamic_cast<const TriangleMesh*>(shape.get()))
            triangles += mesh->triangle_count();
    }
    shadow_bvh_ = triangles <= kMaxShadowBvhTriangles;
    if (shadow_bvh_)
        charge_scene_memory(kShadowBvhBytesPerTriangle * triangles, "the shadow rays' BVH");
    const bool direct = shadow_bvh_ && analytic_shapes <= kMaxDirectOccluders;
    for (const auto& shape : shapes_) {
        unsigned id = shape->attach(device_, rtc_scene_);
        const auto* analytic = dynamic_cast<const AnalyticShape*>(shape.get());
        if (analytic && direct && !analytic->alpha)  // a cut-out needs its Embree callback
            direct_occluders_.push_back(analytic);
        else if (shadow_bvh_)
            also_for_occlusion(id);
        if (id >= geometry_to_shape_.size()) geometry_to_shape_.resize(id + 1, nullptr);
        geometry_to_shape_[id] = shape.get();
        if (id >= plain_meshes_.size()) plain_meshes_.resize(id + 1, nullptr);
        const auto* mesh = dynamic_cast<const TriangleMesh*>(shape.get());
        if (mesh && mesh->has_hit_records() && mesh->bsdf && !mesh->bsdf->varies())
            plain_meshes_[id] = mesh;
        bounds_.expand(shape->bounds());
        has_media_ = has_media_ || shape->interior || shape->exterior;
    }
    for (const auto& instance : instances_) {
        const unsigned id = instance->attach(device_, rtc_scene_);
        if (shadow_bvh_) also_for_occlusion(id);
        if (id >= geometry_to_instance_.size()) geometry_to_instance_.resize(id + 1, nullptr);
        geometry_to_instance_[id] = instance.get();
        bounds_.expand(instance->bounds());
        has_media_ = has_media_ || instance->group().has_media();
    }
    has_media_ = has_media_ || camera_medium_;
    rtcCommitScene(rtc_scene_);
    rtcCommitScene(occlusion_scene_);
    if (bounds_.empty()) {
        // Only infinite lights (or nothing): a unit sphere around the camera keeps the
        // infinite-light emission disk well defined.
        bounds_.expand(camera_.position() - Vec3(1.0f));
        bounds_.expand(camera_.position() + Vec3(1.0f));
    }
    sphere_.center = (bounds_.lo + bounds_.hi) * 0.5f;
    sphere_.radius = std::max(0.5f * length(bounds_.hi - bounds_.lo), 1e-6f);
    // Offsets proportional to the scene size keep spawning scale invariant (1e-3 ... 1e4).
    ray_epsilon_ = 1e-5f * sphere_.radius;

    std::vector<float> weights;
    for (const auto& light : lights_) {
        light->preprocess(sphere_);
        weights.push_back(std::max(0.0f, light->power().luminance()));
        if (light->is_infinite_background()) background_lights_.push_back(light.get());
    }
    light_distribution_ = Distribution1D(weights);
    for (size_t i = 0; i < lights_.size(); ++i)
        light_pick_probability_[lights_[i].get()] = light_distribution_.discrete_probability(i);
    build_volume_lights();
    committed_ = true;
}

namespace {

bool within_scene_limits(const Aabb& b) {
    bool ok = !b.empty();
    for (int a = 0; a < 3 && ok; ++a)
        ok = std::isfinite(b.lo[a]) && std::isfinite(b.hi[a]) &&
             std::abs(b.lo[a]) <= kMaxSceneCoordinate && std::abs(b.hi[a]) <= kMaxSceneCoordinate;
    return ok;
}

}  // namespace

bool within_scene_limits(const Shape& shape) {
    return std::isfinite(shape.surface_area()) && within_scene_limits(shape.bounds());
}

bool within_scene_limits(const Instance& instance) {
    return within_scene_limits(instance.bounds());
}

void Scene::count_invalid_ray() const {
    invalid_rays_.fetch_add(1, std::memory_order_relaxed);
    count_thread_invalid_ray();  // the render this thread works for
}

bool Scene::fill_other_hit(const Ray& ray, const RTCRayHit& rh, HitDetail detail,
                           SurfaceInteraction& si) const {
    if (rh.hit.instID[0] != RTC_INVALID_GEOMETRY_ID)
        geometry_to_instance_[rh.hit.instID[0]]->fill_interaction(
            ray, rh.ray.tfar, rh.hit.geomID, rh.hit.primID, rh.hit.u, rh.hit.v, detail, si);
    else
        geometry_to_shape_[rh.hit.geomID]->fill_interaction(ray, rh.ray.tfar, rh.hit.primID,
                                                            rh.hit.u, rh.hit.v, detail, si);
    if (si.bsdf->varies() || si.hit_bsdf) [[unlikely]]
        resolve_material(si);
    return true;
}

void Scene::resolve_material(SurfaceInteraction& si) const {
    // Materials that vary over the surface: the shapes filled si.uv, dpdu and dpdv for them
    // (uv_wanted, core/shapes/uv_wanted.h), which the shading-frame hook and at() read.
    if (si.bsdf->varies()) {
        si.shading = si.bsdf->shading_frame(si);  // normal and bump maps
        si.hit_bsdf = si.bsdf->at(si.uv);
        si.bsdf = si.hit_bsdf.get();
    } else if (si.hit_bsdf) {
        si.hit_bsdf.reset();  // an interaction reused from a textured hit
    }
}

float Scene::closest_hit_distance(const Ray& ray) const {
    if (!embree_accepts(ray)) [[unlikely]] {
        count_invalid_ray();
        return kInfinity;
    }
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    RTCRayHit rh = to_rtc_ray_hit(ray);
    rtcIntersect1(rtc_scene_, &context, &rh);
    return rh.hit.geomID == RTC_INVALID_GEOMETRY_ID ? kInfinity : rh.ray.tfar;
}

void Scene::also_for_occlusion(unsigned geometry_id) {
    // Embree shares a geometry between scenes: its buffers and callbacks are not copied.
    rtcAttachGeometry(occlusion_scene_, rtcGetGeometry(rtc_scene_, geometry_id));
}

bool Scene::occluded(const Ray& ray) const {
    if (!embree_accepts(ray)) [[unlikely]] {
        count_invalid_ray();
        return false;
    }
    // The same test with the same numbers as the shapes' Embree callbacks
    // (core/shapes/user_geometry.cpp), without Embree's traversal around it.
    const float origin[3] = {ray.origin.x, ray.origin.y, ray.origin.z};
    const float direction[3] = {ray.direction.x, ray.direction.y, ray.direction.z};
    for (const AnalyticShape* shape : direct_occluders_)
        if (shape->nearest_hit(origin, direction, ray.t_min, ray.t_max)) return true;
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    RTCRay r = to_rtc_ray(ray);
    rtcOccluded1(shadow_bvh_ ? occlusion_scene_ : rtc_scene_, &context, &r);
    return r.tfar < 0;
}

void Scene::occluded(const Ray* rays, size_t count, bool* blocked) const {
    // Embree's stream query takes at most this many rays a call here (a buffer on the stack).
    constexpr size_t kChunk = 64;
    RTCRay batch[kChunk];
    size_t slot_of[kChunk];
    for (size_t begin = 0; begin < count; begin += kChunk) {
        const size_t end = std::min(count, begin + kChunk);
        size_t n = 0;
        for (size_t i = begin; i < end; ++i) {
            const Ray& ray = rays[i];
            blocked[i] = false;
            if (!embree_accepts(ray)) [[unlikely]] {
                count_invalid_ray();
                continue;
            }
            const float origin[3] = {ray.origin.x, ray.origin.y, ray.origin.z};
            const float direction[3] = {ray.direction.x, ray.direction.y, ray.direction.z};
            bool hit = false;
            for (const AnalyticShape* shape : direct_occluders_)
                if (shape->nearest_hit(origin, direction, ray.t_min, ray.t_max)) {
                    hit = true;
                    break;
                }
            if (hit) {
                blocked[i] = true;
                continue;
            }
            batch[n] = to_rtc_ray(ray);
            slot_of[n++] = i;
        }
        if (n == 0) continue;
        RTCIntersectContext context;
        rtcInitIntersectContext(&context);
        context.flags = RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT;
        rtcOccluded1M(shadow_bvh_ ? occlusion_scene_ : rtc_scene_, &context, batch, unsigned(n),
                      sizeof(RTCRay));
        for (size_t k = 0; k < n; ++k) blocked[slot_of[k]] = batch[k].tfar < 0;
    }
}

Ray Scene::spawn_ray(const Vec3& p, const Vec3& n, const Vec3& d) const {
    // Offset along the normal to the side the ray leaves from; the size grows with |p| because
    // float spacing does, and with the scene because intersection error does.
    float eps = ray_epsilon_ + 1e-6f * max_abs_component(p);
    Vec3 offset = n * (dot(n, d) >= 0 ? eps : -eps);
    return Ray(p + offset, d, 0.0f, kInfinity);
}

Ray Scene::spawn_ray_to(const Vec3& p, const Vec3& n, const Vec3& target,
                        const Vec3& n_target) const {
    Vec3 d0 = target - p;
    Ray ray = spawn_ray(p, n, d0);
    Vec3 end = target;
    if (length_squared(n_target) > 0) {
        float eps = ray_epsilon_ + 1e-6f * max_abs_component(target);
        end = target + n_target * (dot(n_target, -d0) >= 0 ? eps : -eps);
    }
    Vec3 d = end - ray.origin;
    float dist = length(d);
    ray.direction = dist > 0 ? d / dist : normalize(d0);
    ray.t_max = dist * (1.0f - 1e-5f);
    return ray;
}

Ray Scene::spawn_ray_to_infinity(const Vec3& p, const Vec3& n, const Vec3& d) const {
    return spawn_ray(p, n, d);
}

const Light* Scene::sample_light(float u, float* pick_probability) const {
    if (lights_.empty()) {
        if (pick_probability) *pick_probability = 0;
        return nullptr;
    }
    size_t i = light_distribution_.sample_discrete(u, pick_probability);
    return lights_[i].get();
}

float Scene::light_pick_probability(const Light* light) const {
    auto it = light_pick_probability_.find(light);
    return it == light_pick_probability_.end() ? 0.0f : it->second;
}

void Scene::build_volume_lights() {
    for (size_t i = 0; i < media_.size(); ++i) {
        const Medium* medium = media_[i].get();
        if (!medium->is_emissive()) continue;
        const std::string name = medium_names_[i].empty() ? "a medium" : medium_names_[i];
        std::string why;
        const Aabb box = volume_emitter_region(*this, medium, why);
        if (box.empty()) {
            unbounded_emitting_media_.push_back(name + ": " + why);
            continue;
        }
        volume_lights_.push_back(std::make_unique<VolumeEmitter>(*this, *medium, box, name));
    }
    if (volume_lights_.empty()) return;
    std::vector<float> weights;
    for (const auto& light : lights_) emitters_.push_back(light.get());
    for (const auto& light : volume_lights_) emitters_.push_back(light.get());
    for (const Light* light : emitters_)
        weights.push_back(std::max(0.0f, light->power().luminance()));
    emitter_distribution_ = Distribution1D(weights);
    for (size_t i = 0; i < emitters_.size(); ++i)
        emitter_pick_probability_[emitters_[i]] = emitter_distribution_.discrete_probability(i);
}

const Light* Scene::volume_light_of(const Medium* medium) const {
    for (const auto& light : volume_lights_)
        if (light->medium == medium) return light.get();
    return nullptr;
}

const Light* Scene::sample_emitter(float u, float* pick_probability) const {
    if (volume_lights_.empty()) return sample_light(u, pick_probability);
    return emitters_[emitter_distribution_.sample_discrete(u, pick_probability)];
}

float Scene::emitter_pick_probability(const Light* light) const {
    if (volume_lights_.empty()) return light_pick_probability(light);
    auto it = emitter_pick_probability_.find(light);
    return it == emitter_pick_probability_.end() ? 0.0f : it->second;
}

}  // namespace render
