#include "core/image/exr_io.h"

#include <OpenImageIO/imagebuf.h>
#include <OpenImageIO/imageio.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace render {

namespace OIIO = OIIO_NAMESPACE;

void write_exr(const std::filesystem::path& file, const Image& image,
               const std::map<std::string, std::string>& metadata,
               const std::vector<NamedLayer>& layers) {
    auto out = OIIO::ImageOutput::create(file.string());
    if (!out) throw std::runtime_error("cannot write " + file.string() + ": " + OIIO::geterror());
    const int channels = 3 * int(1 + layers.size());
    OIIO::ImageSpec spec(image.width(), image.height(), channels, OIIO::TypeDesc::FLOAT);
    spec.channelnames = {"R", "G", "B"};
    for (const NamedLayer& layer : layers) {
        if (layer.image.width() != image.width() || layer.image.height() != image.height())
            throw std::invalid_argument("layer " + layer.name + " differs in size from the image");
        for (const char* c : {".R", ".G", ".B"}) spec.channelnames.push_back(layer.name + c);
    }
    spec.attribute("compression", "zip");
    for (const auto& [key, value] : metadata) spec.attribute(key, value);
    // Interleave the main image and the layers pixel by pixel, as OIIO expects.
    std::vector<float> pixels(image.pixel_count() * size_t(channels));
    for (size_t i = 0; i < image.pixel_count(); ++i) {
        float* dst = &pixels[i * size_t(channels)];
        for (int c = 0; c < 3; ++c) dst[c] = image.data()[3 * i + c];
        for (size_t l = 0; l < layers.size(); ++l)
            for (int c = 0; c < 3; ++c) dst[3 * (l + 1) + c] = layers[l].image.data()[3 * i + c];
    }
    if (!out->open(file.string(), spec) ||
        !out->write_image(OIIO::TypeDesc::FLOAT, pixels.data()) || !out->close())
        throw std::runtime_error("cannot write " + file.string() + ": " + out->geterror());
}

Image read_image(const std::filesystem::path& file, std::map<std::string, std::string>* metadata) {
    if (!std::filesystem::exists(file))
        throw std::runtime_error("image file not found: " + file.string());
    auto in = OIIO::ImageInput::open(file.string());
    if (!in) throw std::runtime_error("cannot read " + file.string() + ": " + OIIO::geterror());
    const OIIO::ImageSpec& spec = in->spec();
    int channels = spec.nchannels;
    if (spec.width <= 0 || spec.height <= 0 || channels <= 0)
        throw std::runtime_error("empty image: " + file.string());
    std::vector<float> pixels(size_t(spec.width) * spec.height * channels);
    if (!in->read_image(0, 0, 0, channels, OIIO::TypeDesc::FLOAT, pixels.data()))
        throw std::runtime_error("cannot read " + file.string() + ": " + in->geterror());
    if (metadata)
        for (const auto& attr : spec.extra_attribs)
            if (attr.type() == OIIO::TypeDesc::STRING)
                (*metadata)[attr.name().string()] = attr.get_string();
    in->close();
    Image image(spec.width, spec.height);
    for (size_t i = 0; i < image.pixel_count(); ++i) {
        const float* p = &pixels[i * channels];
        Rgb c = channels >= 3 ? Rgb(p[0], p[1], p[2]) : Rgb(p[0]);
        image.set(i, c);
    }
    return image;
}

void write_png_preview(const std::filesystem::path& file, const Image& image,
                       float exposure_scale) {
    std::vector<unsigned char> bytes(image.pixel_count() * 3);
    const float* src = image.data();
    for (size_t i = 0; i < bytes.size(); ++i) {
        float v = std::clamp(src[i] * exposure_scale, 0.0f, 1.0f);
        if (!std::isfinite(v)) v = 0;
        v = v <= 0.0031308f ? 12.92f * v : 1.055f * std::pow(v, 1.0f / 2.4f) - 0.055f;
        bytes[i] = (unsigned char)std::lround(v * 255.0f);
    }
    auto out = OIIO::ImageOutput::create(file.string());
    if (!out) throw std::runtime_error("cannot write " + file.string() + ": " + OIIO::geterror());
    OIIO::ImageSpec spec(image.width(), image.height(), 3, OIIO::TypeDesc::UINT8);
    if (!out->open(file.string(), spec) || !out->write_image(OIIO::TypeDesc::UINT8, bytes.data()) ||
        !out->close())
        throw std::runtime_error("cannot write " + file.string() + ": " + out->geterror());
}

}  // namespace render
