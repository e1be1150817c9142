#pragma once

// Alpha cut-outs, pbrt-v4's semantics: a shape's `alpha` (a constant or a float texture at the
// hit's uv) keeps a hit with probability alpha. 1 is an ordinary hit, 0 a hole; in between the
// hit is kept when a hash of the ray (origin and direction, as pbrt-v4's GeometricPrimitive
// hashes) and of the hit's distance falls below alpha: the same ray decides the same way at the
// same surface point (a shadow ray as a camera ray), and the hits of one ray are independent
// (pbrt-v4 gets that by hashing the continuation ray, which starts at the cut-out hit). The test
// runs inside the intersection itself (Embree's filter functions for meshes, the intersection
// callbacks for analytic shapes), so camera, light and shadow rays all see the same holes.

#include "core/math/vec.h"
#include "core/textures/texture_param.h"

namespace render {

class AlphaCutout {
  public:
    explicit AlphaCutout(FloatParam alpha) : alpha_(std::move(alpha)) {}

    // Whether the ray org + t dir keeps its hit at distance t, surface coordinates uv.
    bool keeps_hit(Vec2 uv, const float org[3], const float dir[3], float t) const;

    // A number in [0, 1) from the ray's origin, direction and hit distance (their float bits).
    static float ray_hash(const float org[3], const float dir[3], float t);

    const FloatParam& alpha() const { return alpha_; }

  private:
    FloatParam alpha_;
};

}  // namespace render
