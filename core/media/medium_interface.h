#pragma once

// Which medium a path is in after a surface event: Mitsuba 3's rule, read from its `volpath`
// (docs/design/media.md, "Which medium a path is in"). A shape that declares a medium on either
// side is a medium transition: whatever happened there (reflection, transmission, a null
// crossing), the path continues in the medium on the side its new direction points to, the
// exterior in front of the geometric normal, the interior behind it, vacuum (null) for a side
// it does not declare. A shape that declares neither keeps the medium the path had. pbrt-v4's
// rule is the same once its loader leaves shapes with equal media on both sides undeclared.
//
// The medium is therefore set by the last declaring interface crossed: leaving a shape puts the
// path in that shape's exterior even inside a larger shape with the same interior.

#include "core/base/interaction.h"
#include "core/base/shape.h"
#include "core/math/vec.h"

namespace render {

class Medium;

inline bool is_medium_transition(const Shape& shape) {
    return shape.interior != nullptr || shape.exterior != nullptr;
}

// The medium of a path leaving a point of `shape` (geometric normal `n`) in direction `d`,
// having been in `current` before. Exactly on the surface (d ⟂ n) counts as the interior, as
// in Mitsuba.
inline const Medium* medium_after_surface(const Shape& shape, const Vec3& n, const Vec3& d,
                                          const Medium* current) {
    if (!is_medium_transition(shape)) return current;
    return dot(d, n) > 0 ? shape.exterior : shape.interior;
}

inline const Medium* medium_after_surface(const SurfaceInteraction& si, const Vec3& d,
                                          const Medium* current) {
    return medium_after_surface(*si.shape, si.geometric_normal, d, current);
}

// Whether a path reaching `shape` (geometric normal `n`) in direction `d` while in `current`
// arrives against the shape's declaration: the shape names another medium, or none, on the side
// the path comes from. Read the other way, the rule puts that side's declared medium in the
// region the path has just crossed, so the region is in one medium for paths crossing it one
// way and in another for paths crossing it the other way; the two readings agree everywhere
// else. The predicate is the same in both directions: a path crossing the region the other way
// arrives against the declaration at its other end.
inline bool arrives_against_declaration(const Shape& shape, const Vec3& n, const Vec3& d,
                                        const Medium* current) {
    return is_medium_transition(shape) && medium_after_surface(shape, n, -d, current) != current;
}

}  // namespace render
