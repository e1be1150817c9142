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

// The tag of SurfaceInteraction's constructor that leaves the hit's fields unset.
struct UnfilledTag {};
inline constexpr UnfilledTag kUnfilled{};

// A ray's hit on a surface, in world space.
//
// Scene::intersect writes every field on a hit (every shape's fill ends in
// Shape::finish_interaction; hit_bsdf is reset or set by the scene). So a caller that reads the
// interaction only after a hit constructs it with kUnfilled, which stores nothing but the empty
// hit_bsdf: the zeros and identity frame of the default constructor were a sixth of the cost of
// a closest hit over bare Embree, stored before rtcIntersect1 and overwritten by every hit
// (docs/results/performance-notes.md, "Closest hits through Scene::intersect"). The value fields
// sit in anonymous unions only so that this constructor may leave them unset (Vec3's members have
// default initialisers); they read and copy as plain members. An interaction built by hand, or
// read after a miss, takes the default constructor: every field zero, the frame the identity.
struct SurfaceInteraction {
    SurfaceInteraction()
        : p(),
          geometric_normal(),
          shading(),
          uv(),
          dpdu(),
          dpdv(),
          t(0),
          prim_id(0),
          prim_uv(),
          shape(nullptr),
          bsdf(nullptr),
          emitter(nullptr) {}
    explicit SurfaceInteraction(UnfilledTag) {}

    // clang-format off
    union { Vec3 p; };  // hit point
    // Unit; the side the shape's winding/orientation calls "outside".
    union { Vec3 geometric_normal; };
    // Shading frame; shading.n is the interpolated (or geometric) normal.
    union { Frame shading; };
    // uv, dp/du and dp/dv are zero unless the material varies or HitDetail::kWithUv was asked
    // for. dp/du and dp/dv of the shape's uv parametrisation (world space, not normalised; zero
    // where the shape has none) orient tangent-space normal maps and give bump maps their
    // surface.
    union { Vec2 uv; };
    union { Vec3 dpdu; };
    union { Vec3 dpdv; };
    union { float t; };  // ray distance
    // The shape's primitive that was hit and the ray tracer's parameters on it (a triangle's
    // barycentrics b1, b2; a bilinear patch's (u, v)): what Shape::pdf_area and
    // Shape::uv_at_hit read, so an emitter hit needs no search for its point.
    union { unsigned prim_id; };
    union { Vec2 prim_uv; };
    union { const Shape* shape; };
    // Never null for a hit (absorbing black if the file had none).
    union { const Bsdf* bsdf; };
    union { const Light* emitter; };  // area light attached to the shape, if any
    // clang-format on
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
