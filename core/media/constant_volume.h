#pragma once

#include "core/media/volume.h"

namespace render {

// Mitsuba's `constvolume`: the same value everywhere (infinite bounds).
class ConstantVolume final : public Volume {
  public:
    // `grey` = one channel (a float value); otherwise RGB.
    explicit ConstantVolume(const Rgb& value, bool grey = false);

    Rgb eval(const Vec3&) const override { return value_; }
    float max_value() const override { return value_.max(); }
    float max_in(const Aabb&) const override { return value_.max(); }
    Aabb bounds() const override;
    int channels() const override { return grey_ ? 1 : 3; }
    std::string to_string() const override;

  private:
    Rgb value_;
    bool grey_;
};

}  // namespace render
