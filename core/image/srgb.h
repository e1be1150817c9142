#pragma once

// The sRGB transfer curve, and which stored images are display-encoded with it.

#include <algorithm>
#include <cctype>
#include <cmath>
#include <string>

namespace render {

// sRGB-encoded value in [0, 1] to linear (IEC 61966-2-1).
inline float srgb_to_linear(float x) {
    return x <= 0.04045f ? x / 12.92f : std::pow((x + 0.055f) / 1.055f, 2.4f);
}

// Integer formats (PNG, JPEG, TGA...) store display-encoded values and are taken as sRGB, as
// Mitsuba does, unless the file's header says they are linear (OpenImageIO's oiio:ColorSpace
// "Linear", e.g. a PNG with gamma 1); floating-point formats (EXR, HDR, PFM) are linear.
inline bool is_srgb_encoded(bool integer_format, const std::string& color_space) {
    if (!integer_format) return false;
    std::string lower(color_space);
    std::transform(lower.begin(), lower.end(), lower.begin(),
                   [](unsigned char c) { return char(std::tolower(c)); });
    return lower.find("linear") == std::string::npos;
}

}  // namespace render
