#pragma once

// The renderable scene: geometry in Embree (one BVH for closest hits, one for shadow rays),
// materials, lights, camera, and the render settings the scene file carried. Built once
// (commit()), immutable and thread-safe afterwards.

#include <embree3/rtcore.h>

#include <atomic>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <unordered_map>
#include <vector>

#include "core/base/interaction.h"
#include "core/base/scene_limits.h"
#include "core/base/shape.h"
#include "core/camera/perspective_camera.h"
#include "core/lights/light.h"
#include "core/materials/bsdf.h"
#include "core/math/ray.h"
#include "core/sampling/distribution.h"
#include "core/scene/embree_ray.h"
#include "core/shapes/triangle_mesh_hit.h"

namespace render {

class AnalyticShape;
class Instance;
class Medium;

// Geometry within the scene's limits (core/base/scene_limits.h): finite bounds within
// kMaxSceneCoordinate of the origin and a finite area.
bool within_scene_limits(const Shape& shape);
// The same for an instance: its world bounds (its group's shapes are checked in their space).
bool within_scene_limits(const Instance& instance);

// Settings a scene file carries (integrator, sampler, film). Command-line options override them.
struct SceneSettings {
    std::string integrator = "path";
    int max_depth = -1;     // Mitsuba's meaning: -1 = unbounded; 1 = directly visible emitters
    int rr_depth = 5;       // Russian roulette starts at this path depth
    int sample_count = 16;  // sampler sample_count (iterations, one sample per pixel each)
};

class TriangleMesh;

class Scene {
  public:
    // The shadow rays' BVH costs ~72 B per triangle (docs/results/performance-notes.md, "Shadow
    // rays through their own BVH"). It is built only for scenes of at most this many
    // top-level triangles (at most ~72 MiB); a larger scene keeps its memory and sends shadow rays
    // through the closest-hit BVH, as before, with every analytic shape in it.
    static constexpr size_t kMaxShadowBvhTriangles = size_t(1) << 20;
    static constexpr uint64_t kShadowBvhBytesPerTriangle = 72;

    Scene();
    ~Scene();
    Scene(const Scene&) = delete;
    Scene& operator=(const Scene&) = delete;

    // --- building (single-threaded, before commit) ---
    // Keeps a BSDF alive for the scene's lifetime and returns the stable pointer.
    const Bsdf* add_bsdf(std::shared_ptr<const Bsdf> bsdf);
    // Adds a shape; `bsdf` may be null (gets an absorbing black diffuse). `emitter` may be null.
    Shape* add_shape(std::unique_ptr<Shape> shape, const Bsdf* bsdf);
    // Adds an instance of a shape group (core/shapes/instance.h); instances never emit.
    void add_instance(std::unique_ptr<Instance> instance);
    // Adds a light (area lights must already be attached to their shape via shape->emitter).
    const Light* add_light(std::unique_ptr<Light> light);
    void set_camera(const PerspectiveCamera& camera) { camera_ = camera; }
    // Keeps a medium alive for the scene's lifetime and returns the stable pointer. `name`
    // describes it in messages (its id and where the scene file defines it).
    const Medium* add_medium(std::shared_ptr<const Medium> medium, std::string name = "");
    // The medium around the camera (null: vacuum).
    void set_camera_medium(const Medium* medium) { camera_medium_ = medium; }
    SceneSettings settings;
    std::string source_file;  // for messages and EXR metadata

    // Builds the Embree BVH, the scene bounding sphere and the light selection distribution.
    // Throws SceneError for a scene that cannot be rendered (e.g. no camera).
    void commit();

    // --- queries (thread-safe after commit) ---
    // Closest hit in (ray.t_min, ray.t_max). Fills every field of `si` and returns true on a
    // hit (so `si` may be constructed with kUnfilled, interaction.h); leaves it as it was on a
    // miss. Its uv and dp/du are zero unless the material varies or with HitDetail::kWithUv.
    // Inline
    // (below the class) for the common case, a triangle mesh with a plain material, so that the
    // caller's SurfaceInteraction is filled without a call frame and the stores of its
    // constructor that the fill overwrites are dropped (docs/results/performance-notes.md,
    // "Closest hits through Scene::intersect").
    bool intersect(const Ray& ray, SurfaceInteraction& si,
                   HitDetail detail = HitDetail::kShading) const;
    // The distance to the closest hit in (ray.t_min, ray.t_max), infinity if none: for callers
    // that need no interaction (no shading frame, uv or per-hit BSDF is built).
    float closest_hit_distance(const Ray& ray) const;
    // True if anything blocks the open segment (ray.t_min, ray.t_max).
    bool occluded(const Ray& ray) const;
    // occluded() for `count` rays at once: blocked[i] = occluded(rays[i]), the shadow BVH
    // queried through Embree's stream query (rtcOccluded1M, incoherent), the direct occluders
    // per ray. The answers may differ from occluded()'s only where the two traversals round
    // differently (a ray through an edge). For measuring whether batches pay
    // (docs/results/performance-notes.md, "Shadow rays in batches").
    void occluded(const Ray* rays, size_t count, bool* blocked) const;
    // The three queries above hand Embree only rays it accepts (embree_accepts,
    // core/scene/embree_ray.h): any other ray is a miss (unoccluded), counted here over the
    // scene's life (every render of it), and in the tally of the render the thread works for
    // (core/scene/invalid_ray_tally.h), which gives RenderStats::invalid_rays.
    uint64_t invalid_rays() const { return invalid_rays_.load(std::memory_order_relaxed); }

    // Ray leaving surface point p (normal n) in direction d, offset so it cannot re-hit the
    // surface it starts on. The offset scales with the scene size and |p|.
    Ray spawn_ray(const Vec3& p, const Vec3& n, const Vec3& d) const;
    // Shadow ray from surface point p (normal n) to point `target` (normal n_target, or zero
    // vector for a point light), offset at both ends.
    Ray spawn_ray_to(const Vec3& p, const Vec3& n, const Vec3& target, const Vec3& n_target) const;
    // Shadow ray from surface point p toward direction d to infinity (for infinite lights).
    Ray spawn_ray_to_infinity(const Vec3& p, const Vec3& n, const Vec3& d) const;

    const PerspectiveCamera& camera() const { return camera_; }
    const Medium* camera_medium() const { return camera_medium_; }
    const std::vector<std::shared_ptr<const Medium>>& media() const { return media_; }
    // The name given to add_medium for media()[i] ("" when none was given).
    const std::string& medium_name(size_t i) const { return medium_names_[i]; }
    // True when a shape bounds a medium or the camera sits in one. Integrators take their
    // medium-aware code paths only then, so surface-only scenes pay nothing for media.
    bool has_media() const { return has_media_; }
    const std::vector<std::unique_ptr<Light>>& lights() const { return lights_; }
    const std::vector<std::unique_ptr<Shape>>& shapes() const { return shapes_; }
    // Instances of shape groups: geometry that is not in shapes() (their groups hold it).
    const std::vector<std::unique_ptr<Instance>>& instances() const { return instances_; }
    // Lights hit by escaping rays (constant, envmap).
    const std::vector<const Light*>& background_lights() const { return background_lights_; }

    // Light selection proportional to power (luminance): a discrete probability per light,
    // not a density.
    const Light* sample_light(float u, float* pick_probability) const;
    float light_pick_probability(const Light* light) const;

    // Emitting media as lights (core/scene/volume_emitter.h), for the bidirectional family
    // only: path tracers keep lights() and collect medium emission along their segments. Built
    // at commit() for every emitting medium whose region is finite; the others are named by
    // unbounded_emitting_media().
    const std::vector<std::unique_ptr<Light>>& volume_lights() const { return volume_lights_; }
    const Light* volume_light_of(const Medium* medium) const;
    // "medium \"glow\" (scene.xml:3): the camera is in it ..." per emitting medium that cannot
    // be a light; empty when there is none.
    const std::vector<std::string>& unbounded_emitting_media() const {
        return unbounded_emitting_media_;
    }
    // Selection by power over lights() and volume_lights() together: with no volume lights the
    // same as sample_light / light_pick_probability (the same draws, the same probabilities).
    const Light* sample_emitter(float u, float* pick_probability) const;
    float emitter_pick_probability(const Light* light) const;

    const SceneSphere& bounding_sphere() const { return sphere_; }
    // The committed Embree scene, for benchmarks that compare against bare Embree queries.
    RTCScene embree_scene() const { return rtc_scene_; }
    const Aabb& bounds() const { return bounds_; }

  private:
    [[gnu::cold]] void count_invalid_ray() const;
    // intersect() out of line: a hit on an instance, an analytic shape or a mesh that is not
    // plain (plain_meshes_), or one that wants uv (through the shape's virtual fill), then
    // resolve_material where the material varies or `si` holds a previous hit's BSDF.
    [[gnu::noinline]] bool fill_other_hit(const Ray& ray, const RTCRayHit& rh, HitDetail detail,
                                          SurfaceInteraction& si) const;
    // A material that varies over the surface resolved at the hit (its shading frame and its
    // BSDF at uv), or the BSDF of a previous textured hit in a reused `si` released.
    [[gnu::noinline]] void resolve_material(SurfaceInteraction& si) const;
    mutable std::atomic<uint64_t> invalid_rays_{0};
    RTCDevice device_ = nullptr;
    RTCScene rtc_scene_ = nullptr;
    RTCScene occlusion_scene_ = nullptr;  // the same geometries, for occluded()
    // The analytic shapes (spheres, disks; not those of instanced groups) when there are at
    // most kMaxDirectOccluders of them: occluded() tests them itself instead of through
    // occlusion_scene_, since Embree's traversal of a user-geometry BVH costs more per shadow
    // ray than a few direct tests (170-290 instructions before any callback on the SmallVCM
    // boxes; veach-mis's four small spheres cost the same either way). With more, the BVH's
    // culling wins and all of them stay in it.
    static constexpr size_t kMaxDirectOccluders = 4;
    bool shadow_bvh_ = false;
    std::vector<const AnalyticShape*> direct_occluders_;
    // Attaches rtc_scene_'s geometry `geometry_id` to occlusion_scene_ as well.
    void also_for_occlusion(unsigned geometry_id);
    std::vector<std::shared_ptr<const Bsdf>> bsdfs_;
    std::vector<std::unique_ptr<Shape>> shapes_;
    std::vector<const Shape*> geometry_to_shape_;  // Embree geometry id -> shape
    // Embree geometry id -> the shape if it is a plain triangle mesh, else null: one with hit
    // records (TriangleMesh::has_hit_records) whose material does not vary, set at commit().
    // intersect() fills its hits inline (TriangleMesh::fill_plain_hit), with no test of the
    // mesh's normals or the material, instead of through the virtual call.
    std::vector<const TriangleMesh*> plain_meshes_;
    std::vector<std::unique_ptr<Instance>> instances_;
    std::vector<const Instance*> geometry_to_instance_;  // Embree geometry id -> instance
    std::vector<std::unique_ptr<Light>> lights_;
    std::vector<const Light*> background_lights_;
    std::vector<std::shared_ptr<const Medium>> media_;
    std::vector<std::string> medium_names_;
    const Medium* camera_medium_ = nullptr;
    bool has_media_ = false;
    Distribution1D light_distribution_;
    std::unordered_map<const Light*, float> light_pick_probability_;
    std::vector<std::unique_ptr<Light>> volume_lights_;
    std::vector<std::string> unbounded_emitting_media_;
    std::vector<const Light*> emitters_;  // lights_ then volume_lights_
    Distribution1D emitter_distribution_;
    std::unordered_map<const Light*, float> emitter_pick_probability_;
    void build_volume_lights();
    PerspectiveCamera camera_;
    SceneSphere sphere_;
    Aabb bounds_;
    float ray_epsilon_ = 1e-4f;  // scaled with the scene at commit()
    bool committed_ = false;
};

inline bool Scene::intersect(const Ray& ray, SurfaceInteraction& si, HitDetail detail) const {
    if (!embree_accepts(ray)) [[unlikely]] {
        count_invalid_ray();
        return false;
    }
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    RTCRayHit rh = to_rtc_ray_hit(ray);
    rtcIntersect1(rtc_scene_, &context, &rh);
    if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return false;
    const TriangleMesh* mesh =
        rh.hit.instID[0] == RTC_INVALID_GEOMETRY_ID ? plain_meshes_[rh.hit.geomID] : nullptr;
    if (!mesh || detail == HitDetail::kWithUv) [[unlikely]]
        return fill_other_hit(ray, rh, detail, si);
    mesh->fill_plain_hit(rh.ray.tfar, rh.hit.primID, rh.hit.u, rh.hit.v, si);
    if (si.hit_bsdf) [[unlikely]]
        resolve_material(si);  // an interaction reused from a textured hit
    return true;
}

}  // namespace render
