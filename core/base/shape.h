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
    // A point with respect to area, uniformly unless pdf_area() says otherwise.
    virtual ShapeSample sample_area(Vec2 u) const = 0;
    // The density sample_area() has at the point a hit on primitive `prim_id` with parameters
    // `prim_uv` reports (SurfaceInteraction::prim_id, prim_uv): 1 / surface_area() unless the
    // shape samples non-uniformly (bilinear patches).
    virtual float pdf_area(unsigned /*prim_id*/, Vec2 /*prim_uv*/) const {
        return 1.0f / surface_area();
    }
    // The primitive and parameters of the surface point p, for callers that only have the
    // point (a light's radiance toward a ray that hit it at p); false when p is on none of
    // them. Shapes whose density is uniform need neither: (0, (0, 0)).
    virtual bool locate(const Vec3& /*p*/, unsigned& prim_id, Vec2& prim_uv) const {
        prim_id = 0;
        prim_uv = Vec2();
        return true;
    }

    virtual std::string to_string() const = 0;

    // The uv a hit at surface point p reports, for lights that only get the point (a textured
    // area light's radiance toward a ray that hit it). Only where has_uv_lookup().
    virtual bool has_uv_lookup() const { return false; }
    virtual Vec2 uv_at(const Vec3& /*p*/) const { return Vec2(); }
    // The uv of the hit (prim_id, prim_uv) at point p: by the hit's parameters where the shape
    // has them (no point lookup), else uv_at(p).
    virtual Vec2 uv_at_hit(unsigned /*prim_id*/, Vec2 /*prim_uv*/, const Vec3& p) const {
        return uv_at(p);
    }

    const Bsdf* bsdf = nullptr;
    const Light* emitter = nullptr;
    // Media on either side (Mitsuba's medium interface): `interior` lies behind the geometric
    // normal, `exterior` in front of it. Null is vacuum.
    const Medium* interior = nullptr;
    const Medium* exterior = nullptr;
    // A cut-out (core/shapes/alpha_cutout.h); null for an opaque shape. Set before the scene
    // commits: the shape's intersection reads it.
    std::shared_ptr<const AlphaCutout> alpha;

  protected:
    // The end of every fill_interaction: the hit's primitive and parameters, this shape, its
    // materials and emitter, and (when `with_uv` is false) zero uv, dp/du and dp/dv.
    void finish_interaction(unsigned prim_id, float u, float v, bool with_uv,
                            SurfaceInteraction& si) const {
        if (!with_uv) {
            si.uv = Vec2();
            si.dpdu = si.dpdv = Vec3(0.0f);
        }
        si.prim_id = prim_id;
        si.prim_uv = Vec2(u, v);
        si.shape = this;
        si.bsdf = bsdf;
        si.emitter = emitter;
    }
};

}  // namespace render
