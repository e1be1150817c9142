#pragma once

// The volume plugin: reading and writing OpenVDB grids (.vdb) through libopenvdb. It is a shared
// library of its own, librender_volume_vdb.so (core/media/vdb_plugin/), loaded with dlopen the
// first time a .vdb file is read or written (core/media/vdb_file.cpp), so that programs linking
// render_core do not load OpenVDB and its ~10 libraries at start-up: relocating libopenvdb's
// ~69,000 symbols was most of the dynamic loader's work, its 26 MiB of tables were mapped
// into every process, and log4cplus started a thread pool before main
// (docs/results/performance-notes.md, "Start-up").
//
// As for the image plugin (core/image/image_plugin.h): a plain C interface, no exception
// crosses it, no allocation is freed on the other side. This header does not include OpenVDB.

#include <cstddef>
#include <string>

extern "C" {

// What `read` reports back to its caller, through the caller's function.
struct RenderVolumeReadSink {
    void* context;
    // Called once, before the voxels are read: the chosen grid's name, the size of its active
    // voxel bounding box and that box's world bounds (lo x, y, z, hi x, y, z). Returns a buffer
    // of xres * yres * zres floats to fill (x fastest), or null when the caller refuses the grid
    // (too large, over the memory budget); `read` then returns 2 and the caller knows why.
    float* (*begin)(void* context, const char* grid_name, int xres, int yres, int zres,
                    const float bounds[6]);
};

struct RenderVolumePlugin {
    int version;  // RENDER_VOLUME_PLUGIN_VERSION
    // Densifies one float grid of the file: the one named "density" if there is one, otherwise
    // the first (docs in core/media/vdb_file.h). Returns 0 on success, 2 when the sink refused,
    // otherwise 1 with a message (which need not name the file) in `error` (NUL-terminated, at
    // most error_size bytes).
    int (*read)(const char* path, const RenderVolumeReadSink* sink, char* error, size_t error_size);
    // Writes xres * yres * zres values (x fastest) as a float grid named "density" covering the
    // world box `bounds` (lo x, y, z, hi x, y, z). Same convention for errors.
    int (*write)(const char* path, int xres, int yres, int zres, const float bounds[6],
                 const float* values, char* error, size_t error_size);
};

// The one symbol the plugin exports.
typedef const RenderVolumePlugin* (*RenderVolumePluginEntry)(void);
const RenderVolumePlugin* render_volume_plugin_v1(void);
}

#define RENDER_VOLUME_PLUGIN_VERSION 1
#define RENDER_VOLUME_PLUGIN_ENTRY "render_volume_plugin_v1"
#define RENDER_VOLUME_PLUGIN_FILE "librender_volume_vdb.so"

namespace render {

// The plugin, loaded on the first call (thread-safe) and kept loaded, from the places
// core/base/dynamic_plugin.h lists ($RENDER_VOLUME_PLUGIN, next to the executable, the build
// tree's bin/, the loader's search). Throws std::runtime_error naming the library, the places
// tried and the loader's message; `purpose` ("to read FILE") says why it was needed.
const RenderVolumePlugin& volume_plugin(const std::string& purpose);

}  // namespace render
