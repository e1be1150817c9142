#pragma once

#include <memory>

#include "core/math/frame.h"
#include "core/math/vec.h"

namespace render {

class Bsdf;
class Light;
class Shape;

// How much of a SurfaceInteraction Scene::intersect fills. The hit point, normals, shading
// frame, materials and emitter always; uv, dp/du and dp/dv only where they are read: by materials
// that vary over the surface (textures, normal and bump maps: the shading-frame hook and at() in
// Scene::intersect) or when the caller asks for them (kWithUv). Filling them at every hit was
// over a quarter of the wrapper's cost over bare Embree (docs/results/performance-notes.md,
// "Closest hits through Scene::intersect").
enum class HitDetail { kShading, kWithUv };

// A ray's hit on a surface, in world space.
struct SurfaceInteraction {
    Vec3 p;                 // hit point
    Vec3 geometric_normal;  // unit; the side the shape's winding/orientation calls "outside"
    Frame shading;          // shading frame; shading.n is the interpolated (or geometric) normal
    // uv, dp/du and dp/dv are zero unless the material varies or HitDetail::kWithUv was asked for.
    Vec2 uv;
    // dp/du and dp/dv of the shape's uv parametrisation (world space, not normalised; zero
    // where the shape has none): orient tangent-space normal maps and give bump maps their
    // surface.
    Vec3 dpdu;
    Vec3 dpdv;
    float t = 0;  // ray distance
    // The shape's primitive that was hit and the ray tracer's parameters on it (a triangle's
    // barycentrics b1, b2; a bilinear patch's (u, v)): what Shape::pdf_area and
    // Shape::uv_at_hit read, so an emitter hit needs no search for its point.
    unsigned prim_id = 0;
    Vec2 prim_uv;
    const Shape* shape = nullptr;
    const Bsdf* bsdf = nullptr;      // never null for a hit (absorbing black if the file had none)
    const Light* emitter = nullptr;  // area light attached to the shape, if any
    // Owns `bsdf` when it was built for this hit: a textured material resolved at uv
    // (Scene::intersect). Null for plain materials, which the scene owns.
    std::shared_ptr<const Bsdf> hit_bsdf;
};

// A point sampled on a shape's surface by area.
struct ShapeSample {
    Vec3 p;
    Vec3 n;              // unit geometric normal at p (facing the shape's outside)
    float pdf_area = 0;  // density with respect to surface area
    Vec2 uv;             // the shape's uv at p, as a hit there would report it
};

}  // namespace render
