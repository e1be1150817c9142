#pragma once

#include <embree3/rtcore.h>

#include <memory>
#include <string>

#include "core/base/interaction.h"
#include "core/math/ray.h"

namespace render {

struct Aabb {
    Vec3 lo{kInfinity}, hi{-kInfinity};
    void expand(const Vec3& p) { lo = min(lo, p), hi = max(hi, p); }
    void expand(const Aabb& b) { lo = min(lo, b.lo), hi = max(hi, b.hi); }
    bool empty() const { return lo.x > hi.x; }
};

// Geometry the renderer can intersect and (for area lights) sample. A shape registers itself
// with Embree once; after a hit the scene asks the shape to fill in the interaction.
class Medium;
class AlphaCutout;

class Shape {
  public:
    virtual ~Shape() = default;

    // Creates, commits and attaches this shape's Embree geometry; returns its geometry id.
    virtual unsigned attach(RTCDevice device, RTCScene scene) const = 0;
    // Completes an interaction from Embree's hit record (primitive id and barycentrics u, v);
    // si.uv, dpdu and dpdv only if uv_wanted(*this, detail) (core/shapes/uv_wanted.h), else zero.
    virtual void fill_interaction(const Ray& ray, float t, unsigned prim_id, float u, float v,
                                  HitDetail detail, SurfaceInteraction& si) const = 0;

    virtual Aabb bounds() const = 0;
    virtual float surface_area() const = 0;
    // Uniform point with respect to area: pdf_area = 1 / surface_area().
    virtual ShapeSample sample_area(Vec2 u) const = 0;

    virtual std::string to_string() const = 0;

    // The uv a hit at surface point p reports, for lights that only get the point (a textured
    // area light's radiance toward a ray that hit it). Only where has_uv_lookup().
    virtual bool has_uv_lookup() const { return false; }
    virtual Vec2 uv_at(const Vec3& /*p*/) const { return Vec2(); }

    const Bsdf* bsdf = nullptr;
    const Light* emitter = nullptr;
    // Media on either side (Mitsuba's medium interface): `interior` lies behind the geometric
    // normal, `exterior` in front of it. Null is vacuum.
    const Medium* interior = nullptr;
    const Medium* exterior = nullptr;
    // A cut-out (core/shapes/alpha_cutout.h); null for an opaque shape. Set before the scene
    // commits: the shape's intersection reads it.
    std::shared_ptr<const AlphaCutout> alpha;
};

}  // namespace render
