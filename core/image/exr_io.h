#pragma once

// Image files. OpenEXR is read and written with OpenEXR itself (linked into render_core);
// everything else (reading .hdr, .png... and writing the PNG preview) goes through
// OpenImageIO in the image plugin, a shared library loaded only when such a file is used
// (core/image/image_plugin.h; docs/results/performance-notes.md, "Start-up"). This header includes
// neither library: OIIO and protobuf headers cannot share a translation unit
// (DEPENDENCIES.md, trap 2).

#include <filesystem>
#include <map>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/image/image.h"

namespace render {

// Writes linear float RGB OpenEXR (whatever the file's extension): channels R, G, B and, for
// each layer (same size as `image`), NAME.R, NAME.G, NAME.B; ZIP compression; `metadata` as
// string attributes of the header, plus capDate (local time, as OpenImageIO writes it). Throws
// std::invalid_argument for a layer of another size, std::runtime_error naming the file when
// it cannot be written.
void write_exr(const std::filesystem::path& file, const Image& image,
               const std::map<std::string, std::string>& metadata = {},
               const std::vector<NamedLayer>& layers = {});

// A file that cannot be read: what() is "cannot read FILE: REASON", reason() the REASON alone.
class ImageFileError : public std::runtime_error {
  public:
    ImageFileError(const std::filesystem::path& file, const std::string& reason)
        : std::runtime_error("cannot read " + file.string() + ": " + reason), reason_(reason) {}
    const std::string& reason() const { return reason_; }

  private:
    std::string reason_;
};

// An image file's pixels as stored, `channels` floats per pixel, rows top to bottom.
struct ImageFileData {
    int width = 0, height = 0, channels = 0;
    std::vector<float> pixels;
    bool integer_format = false;  // stored as integers (PNG, JPEG...): display-encoded values
    std::string color_space;      // OpenImageIO's oiio:ColorSpace for plugin reads, else ""
    std::map<std::string, std::string> metadata;  // the header's string attributes
};

// Reads an image file. OpenEXR files (recognised by their magic number) are read with OpenEXR:
// the channels R, G, B (3 channels), else Y or a lone channel (1), of the first part's data
// window, as float; an EXR this does not cover (other channel sets, subsampled or integer
// channels) and every other format go through the image plugin (OpenImageIO), whose channels
// are the file's, in OpenImageIO's order. Throws ImageFileError (a missing plugin names itself
// in the reason).
ImageFileData read_image_file(const std::filesystem::path& file);

// Reads any image (EXR, HDR, PNG...; as read_image_file) as linear float RGB (alpha dropped,
// grey replicated). `metadata` (optional) receives the header's string attributes, under the
// file's names (capDate for an EXR's date). Throws std::runtime_error naming the file.
Image read_image(const std::filesystem::path& file,
                 std::map<std::string, std::string>* metadata = nullptr);

// The layer NAME (channels NAME.R, NAME.G, NAME.B, as write_exr writes them) of an OpenEXR
// file, or nullopt when the file has no such layer. Throws ImageFileError when the file cannot
// be read.
std::optional<Image> read_exr_layer(const std::filesystem::path& file, const std::string& layer);

// 8-bit sRGB PNG preview: exposure scale, then clamp and the sRGB curve (written by the image
// plugin, in the format the extension names).
void write_png_preview(const std::filesystem::path& file, const Image& image,
                       float exposure_scale = 1.0f);

}  // namespace render
