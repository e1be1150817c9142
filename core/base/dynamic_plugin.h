#pragma once

// Loading a plugin: a shared library of our own that core dlopens the first time it is needed,
// so that programs do not load its heavy dependencies at start-up
// (docs/results/performance-notes.md, "Start-up"). Used by the image plugin
// (core/image/image_plugin.h, OpenImageIO) and the volume plugin (core/media/vdb_plugin.h,
// OpenVDB).

#include <functional>
#include <string>

namespace render {

struct DynamicPluginSpec {
    const char* file;         // e.g. "librender_image_oiio.so"
    const char* environment;  // the variable that, when set, names the only file tried
    const char* entry;        // the one exported symbol, a function taking no argument
};

// Looks in this order: the file $environment if set (and nowhere else); `file` next to the
// running executable; in the build tree's bin/ (the tests); the dynamic loader's own search
// (LD_LIBRARY_PATH, ld.so.cache). For the first candidate that loads, calls `accept` with its
// entry symbol (null if missing); a non-null result is returned and the library stays loaded,
// null (with `*why` set) rejects it and the search goes on. Returns null when nothing was
// accepted, with every candidate and its reason appended to `*failures`.
const void* load_dynamic_plugin(
    const DynamicPluginSpec& spec,
    const std::function<const void*(void* entry, std::string* why)>& accept, std::string* failures);

}  // namespace render
