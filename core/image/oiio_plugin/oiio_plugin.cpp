// librender_image_oiio.so: image I/O through OpenImageIO, loaded by core on demand
// (core/image/image_plugin.h). Not part of render_core; only this file includes OIIO.

#include <OpenImageIO/imageio.h>

#include <cstdio>
#include <exception>
#include <optional>
#include <string>
#include <vector>

#include "core/image/image_plugin.h"

namespace {

namespace OIIO = OIIO_NAMESPACE;

void set_error(char* error, size_t error_size, const std::string& message) {
    if (!error || error_size == 0) return;
    std::snprintf(error, error_size, "%s", message.empty() ? "unknown error" : message.c_str());
}

// The C interface's convention around a body that returns an error message (nullopt: success):
// 0 on success, else 1 with `error` filled; exceptions become messages.
template <class Body>
int guarded(char* error, size_t error_size, Body&& body) {
    std::optional<std::string> message;
    try {
        message = body();
    } catch (const std::exception& e) {
        message = e.what();
    } catch (...) {
        message = "unknown exception in OpenImageIO";
    }
    if (!message) return 0;
    set_error(error, error_size, *message);
    return 1;
}

int read(const char* path, const RenderImageReadSink* sink, char* error, size_t error_size) {
    return guarded(error, error_size, [&]() -> std::optional<std::string> {
        auto in = OIIO::ImageInput::open(path);
        if (!in) {
            return std::string(OIIO::geterror());
        }
        const OIIO::ImageSpec& spec = in->spec();
        const int channels = spec.nchannels;
        if (spec.width <= 0 || spec.height <= 0 || channels <= 0) {
            return std::string("the image has no pixels");
        }
        const bool is_integer = spec.format.basetype != OIIO::TypeDesc::FLOAT &&
                                spec.format.basetype != OIIO::TypeDesc::HALF &&
                                spec.format.basetype != OIIO::TypeDesc::DOUBLE;
        const std::string color_space = spec.get_string_attribute("oiio:ColorSpace");
        float* pixels = sink->begin(sink->context, spec.width, spec.height, channels,
                                    is_integer ? 1 : 0, color_space.c_str());
        if (!pixels) {
            return std::string("out of memory");
        }
        if (!in->read_image(0, 0, 0, channels, OIIO::TypeDesc::FLOAT, pixels)) {
            return std::string(in->geterror());
        }
        for (const auto& attr : spec.extra_attribs)
            if (attr.type() == OIIO::TypeDesc::STRING)
                sink->attribute(sink->context, attr.name().c_str(), attr.get_string().c_str());
        in->close();
        return std::nullopt;
    });
}

int write_rgb8(const char* path, int width, int height, const unsigned char* rgb, char* error,
               size_t error_size) {
    return guarded(error, error_size, [&]() -> std::optional<std::string> {
        auto out = OIIO::ImageOutput::create(path);
        if (!out) {
            return std::string(OIIO::geterror());
        }
        OIIO::ImageSpec spec(width, height, 3, OIIO::TypeDesc::UINT8);
        if (!out->open(path, spec) || !out->write_image(OIIO::TypeDesc::UINT8, rgb) ||
            !out->close()) {
            return std::string(out->geterror());
        }
        return std::nullopt;
    });
}

const RenderImagePlugin kPlugin = {RENDER_IMAGE_PLUGIN_VERSION, &read, &write_rgb8};

}  // namespace

extern "C" __attribute__((visibility("default"))) const RenderImagePlugin* render_image_plugin_v1(
    void) {
    return &kPlugin;
}
