#pragma once

// The light interface, shaped for the whole bidirectional family (the semantics follow the
// VCM reference implementation, SmallVCM): every sampling routine also reports the densities
// that the *other* techniques would have used for the same path, so MIS needs nothing more.
//
// Density conventions:
//   pdf_direct_a   density with which illuminate() picks this point on the light, w.r.t. area
//                  (for infinite lights: w.r.t. solid angle, and pdf_direct_w is the same).
//   pdf_direct_w   illuminate()'s density w.r.t. solid angle at the receiving point.
//   pdf_emission_w density of emit() producing this (point, direction) pair: the area density
//                  of the origin times the solid-angle density of the direction.
// For delta lights (point, directional) the delta densities are reported as 1 (discrete).
// Light selection probabilities are *not* included; the scene's light distribution gives them.

#include <memory>
#include <string>

#include "core/base/interaction.h"
#include "core/math/vec.h"

namespace render {

class Medium;
class VolumeEmitter;

// The scene's bounding sphere: infinite and directional lights emit from a disk of this radius.
struct SceneSphere {
    Vec3 center;
    float radius = 1.0f;
};

struct LightIlluminateSample {
    Vec3 wi;             // unit direction from the receiving point toward the light
    float distance = 0;  // to the sampled point; infinity for infinite and directional lights
    Rgb radiance;        // Le arriving along -wi, not divided by any pdf
    float pdf_direct_w = 0;
    float pdf_emission_w = 0;
    float cos_at_light = 1;  // cosine between the light's normal and -wi (1 when not defined)
};

struct LightEmitSample {
    Vec3 origin;
    Vec3 direction;  // unit
    // Le * cos_at_light (SmallVCM's "energy"): divide by (selection probability *
    // pdf_emission_w) to get the light path's throughput.
    Rgb energy;
    float pdf_emission_w = 0;
    float pdf_direct_a = 0;
    float cos_at_light = 1;
};

struct LightRadiance {
    Rgb radiance;  // Le toward the viewer; black from the back of a one-sided emitter
    float pdf_direct_a = 0;
    float pdf_emission_w = 0;
};

class Light {
  public:
    virtual ~Light() = default;

    // Called once after the scene geometry is known (bounding sphere for infinite lights).
    virtual void preprocess(const SceneSphere& scene_sphere) { scene_sphere_ = scene_sphere; }

    // Samples a point on the light as seen from `ref` (next-event estimation / connection).
    // Returns false when the sample carries no energy.
    virtual bool illuminate(const Vec3& ref, Vec2 u, LightIlluminateSample& out) const = 0;

    // The point on a finite light that illuminate(ref, u) connects to: for every finite light
    // here that choice depends on u alone, never on ref. Equi-angular sampling needs the light
    // point before it picks the receiving point. False for infinite lights.
    virtual bool sample_position(Vec2 /*u*/, Vec3& /*position*/) const { return false; }

    // Samples an emitted ray (start of a light path).
    virtual bool emit(Vec2 u_position, Vec2 u_direction, LightEmitSample& out) const = 0;

    // Radiance leaving the light toward -ray_direction, for a ray that hit it at `hit_point`
    // with geometric normal `hit_normal` (area lights), or escaped in `ray_direction`
    // (infinite lights; hit_point and hit_normal are ignored).
    virtual LightRadiance radiance(const Vec3& hit_point, const Vec3& hit_normal,
                                   const Vec3& ray_direction) const = 0;
    // radiance() for a ray that hit this light's shape, as Scene::intersect reported the hit:
    // area lights read the hit's primitive and parameters instead of searching for the point.
    virtual LightRadiance radiance_at(const SurfaceInteraction& hit,
                                      const Vec3& ray_direction) const {
        return radiance(hit.p, hit.geometric_normal, ray_direction);
    }

    // Total emitted power (approximate for envmaps): drives light selection.
    virtual Rgb power() const = 0;

    virtual bool is_delta() const = 0;   // position or direction is a delta (point, directional)
    virtual bool is_finite() const = 0;  // false for directional, constant and envmap lights
    virtual bool is_infinite_background() const { return false; }  // seen by escaping rays
    // An emitting medium as a light of the bidirectional family (volume_emitter.h); null for
    // every other light.
    virtual const VolumeEmitter* as_volume() const { return nullptr; }

    virtual std::string to_string() const = 0;

    // The medium that light paths start in (finite lights; null: vacuum). An area light emits
    // into its shape's exterior.
    const Medium* medium = nullptr;

  protected:
    SceneSphere scene_sphere_;
};

}  // namespace render
