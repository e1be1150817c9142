#pragma once

// The image plugin: the part of image I/O that needs OpenImageIO (reading images that are not
// OpenEXR, such as .hdr and .png environment maps, and writing the PNG preview). It is a shared
// library of its own, librender_image_oiio.so (core/image/oiio_plugin/), loaded with dlopen the
// first time such a file is read or written, so that programs linking render_core do not load
// OpenImageIO's ~250 shared libraries at start-up (docs/results/performance-notes.md, "Start-up").
//
// The interface is plain C so that nothing but these declarations is shared between the two
// sides: no exception crosses it, no allocation is freed on the other side. This header does
// not include OpenImageIO (DEPENDENCIES.md, trap 2).

#include <cstddef>
#include <string>

extern "C" {

// What `read` reports back to its caller, through the caller's functions.
struct RenderImageReadSink {
    void* context;
    // Called once, before the pixels are read: the image's size and channel count, whether it
    // is stored as integers (PNG, JPEG...: display-encoded values) and OIIO's color space name
    // ("" if none). Returns a buffer of width * height * channels floats to fill, or null (out
    // of memory, sizes refused).
    float* (*begin)(void* context, int width, int height, int channels, int integer_format,
                    const char* color_space);
    // Called once per string attribute of the file's header.
    void (*attribute)(void* context, const char* name, const char* value);
};

struct RenderImagePlugin {
    int version;  // RENDER_IMAGE_PLUGIN_VERSION
    // Reads the first subimage of any file OpenImageIO reads as float pixels (integer formats
    // scaled to [0, 1]). Returns 0 on success, otherwise writes a message (which need not name
    // the file) into `error` (NUL-terminated, at most error_size bytes) and returns non-zero.
    int (*read)(const char* path, const RenderImageReadSink* sink, char* error, size_t error_size);
    // Writes 8-bit RGB pixels (rows top to bottom) in the format the file name's extension
    // names (PNG for the preview). Same convention for errors.
    int (*write_rgb8)(const char* path, int width, int height, const unsigned char* rgb,
                      char* error, size_t error_size);
};

// The one symbol the plugin exports.
typedef const RenderImagePlugin* (*RenderImagePluginEntry)(void);
const RenderImagePlugin* render_image_plugin_v1(void);
}

#define RENDER_IMAGE_PLUGIN_VERSION 1
#define RENDER_IMAGE_PLUGIN_ENTRY "render_image_plugin_v1"
#define RENDER_IMAGE_PLUGIN_FILE "librender_image_oiio.so"

namespace render {

// The plugin, loaded on the first call (thread-safe) and kept loaded. Looks in this order:
// the file $RENDER_IMAGE_PLUGIN if set (and nowhere else); librender_image_oiio.so next to the
// running executable; in the build tree's bin/ (the tests); the dynamic loader's own search
// (LD_LIBRARY_PATH, ld.so.cache). Throws std::runtime_error naming the library, the places
// tried and the loader's message; `purpose` ("to read FILE") says why it was needed.
const RenderImagePlugin& image_plugin(const std::string& purpose);

}  // namespace render
