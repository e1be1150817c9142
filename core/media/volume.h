#pragma once

// Volume data: a 3-D field in world space (Mitsuba 3's `volume` plugins), used by the
// heterogeneous medium for its extinction and albedo. A volume has 1 channel (grey: eval
// returns the same value in r, g and b) or 3 (RGB).

#include <array>
#include <string>

#include "core/base/shape.h"
#include "core/math/vec.h"

namespace render {

class Volume {
  public:
    virtual ~Volume() = default;

    // The value at world point p; zero outside bounds().
    virtual Rgb eval(const Vec3& p) const = 0;
    // Maximum of eval over all points and channels.
    virtual float max_value() const = 0;
    // An upper bound of eval (all channels) over the world box `world_box`; conservative: it
    // may exceed the true maximum, never fall below it. Used to build majorant grids.
    virtual float max_in(const Aabb& world_box) const = 0;
    // World-space bounding box of the non-zero region; infinite for constant volumes.
    virtual Aabb bounds() const = 0;
    virtual int channels() const = 0;
    // Voxels along each axis of the data (1 for analytic volumes): sizes majorant grids.
    virtual std::array<int, 3> resolution() const { return {1, 1, 1}; }
    virtual std::string to_string() const = 0;
};

// True when every side of the box is finite (a bounded, non-empty region).
inline bool is_bounded(const Aabb& b) {
    return !b.empty() && is_finite(b.lo) && is_finite(b.hi);
}

}  // namespace render
