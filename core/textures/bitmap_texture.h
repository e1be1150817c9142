#pragma once

// An image as a texture (Mitsuba's `bitmap`): any file read_image_file reads (OpenEXR directly,
// everything else through the OpenImageIO plugin). Integer formats (PNG, JPEG...) are sRGB-
// decoded to linear unless `raw` is set; floating-point formats are linear. One- and
// two-channel images (Y, YA) are grey, four-channel ones (RGBA) drop alpha.
//
// Lookups follow Mitsuba: uv (0, 0) is the top-left corner of the image, texel (i, j) has its
// centre at ((i + 0.5) / width, (j + 0.5) / height); `bilinear` interpolates the four nearest
// texel centres, `nearest` takes the texel that contains uv; `repeat`, `mirror` and `clamp`
// decide which texel an index outside the image stands for.

#include <memory>
#include <string>
#include <vector>

#include "core/base/properties.h"
#include "core/textures/texture.h"
#include "core/textures/uv_transform.h"

namespace render {

class BitmapTexture final : public Texture {
  public:
    enum class Filter { Bilinear, Nearest };
    enum class Wrap { Repeat, Mirror, Clamp };

    // `texels`: width * height linear values, rows top to bottom.
    BitmapTexture(std::vector<Rgb> texels, int width, int height, Filter filter, Wrap wrap,
                  const UvTransform& to_uv, std::string name);

    // Parameters: `filename` (required), `raw` (false), `filter_type` (bilinear | nearest),
    // `wrap_mode` (repeat | mirror | clamp), `to_uv`; `format` and `accel` are accepted and
    // have no effect (texels are always stored as float).
    static std::shared_ptr<const Texture> create(const Properties& props);

    Rgb eval(Vec2 uv) const override;
    Rgb mean() const override { return mean_; }
    float min_value() const override { return min_; }
    float max_value() const override { return max_; }
    std::string to_string() const override;

    int width() const { return width_; }
    int height() const { return height_; }
    // The stored (linear) texel at column x, row y; x and y in range.
    const Rgb& texel(int x, int y) const { return texels_[size_t(y) * size_t(width_) + size_t(x)]; }

  private:
    std::vector<Rgb> texels_;
    int width_, height_;
    Filter filter_;
    Wrap wrap_;
    UvTransform to_uv_;
    std::string name_;
    Rgb mean_;
    float min_ = 0, max_ = 0;
};

}  // namespace render
