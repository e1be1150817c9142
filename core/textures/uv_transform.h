#pragma once

// Mitsuba's `to_uv`: a 2D affine map of texture coordinates, written as a 4x4 <transform>
// (scale, translate, rotate about z) of which the x/y rows and columns and the translation are
// kept, as Mitsuba reduces a 4x4 transform to its 3x3 uv form.

#include <cmath>

#include "core/math/transform.h"
#include "core/math/vec.h"

namespace render {

class UvTransform {
  public:
    UvTransform() = default;  // identity
    explicit UvTransform(const Transform& t) {
        const Transform::Matrix& m = t.matrix();
        a_ = float(m[0][0]), b_ = float(m[0][1]), c_ = float(m[0][3]);
        d_ = float(m[1][0]), e_ = float(m[1][1]), f_ = float(m[1][3]);
        identity_ = a_ == 1 && b_ == 0 && c_ == 0 && d_ == 0 && e_ == 1 && f_ == 0;
    }

    Vec2 apply(Vec2 uv) const {
        if (identity_) return uv;
        return {a_ * uv.x + b_ * uv.y + c_, d_ * uv.x + e_ * uv.y + f_};
    }
    bool is_identity() const { return identity_; }
    bool is_finite() const {
        return std::isfinite(a_) && std::isfinite(b_) && std::isfinite(c_) && std::isfinite(d_) &&
               std::isfinite(e_) && std::isfinite(f_);
    }

  private:
    // u' = a u + b v + c, v' = d u + e v + f
    float a_ = 1, b_ = 0, c_ = 0, d_ = 0, e_ = 1, f_ = 0;
    bool identity_ = true;
};

}  // namespace render
