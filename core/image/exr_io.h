#pragma once

// Image files through OpenImageIO. This header deliberately does not include OIIO: OIIO and
// protobuf headers cannot share a translation unit (DEPENDENCIES.md, trap 2).

#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "core/image/image.h"

namespace render {

// Writes linear float RGB OpenEXR; `metadata` becomes string attributes in the header and
// `layers` extra channels (same size as `image`). Throws std::runtime_error with OIIO's
// message on failure.
void write_exr(const std::filesystem::path& file, const Image& image,
               const std::map<std::string, std::string>& metadata = {},
               const std::vector<NamedLayer>& layers = {});

// Reads any image OIIO can read (EXR, HDR, PNG...) as linear float RGB (alpha dropped, grey
// replicated). `metadata` (optional) receives the header's string attributes.
Image read_image(const std::filesystem::path& file,
                 std::map<std::string, std::string>* metadata = nullptr);

// 8-bit sRGB PNG preview: exposure scale, then clamp and the sRGB curve.
void write_png_preview(const std::filesystem::path& file, const Image& image,
                       float exposure_scale = 1.0f);

}  // namespace render
