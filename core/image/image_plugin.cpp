#include "core/image/image_plugin.h"

#include <dlfcn.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <stdexcept>
#include <vector>

namespace render {
namespace {

const RenderImagePlugin* load_plugin(std::string* failures) {
    std::vector<std::string> candidates;
    const char* forced = std::getenv("RENDER_IMAGE_PLUGIN");
    if (forced && *forced) {
        candidates.push_back(forced);
    } else {
        std::error_code ec;
        std::filesystem::path exe = std::filesystem::read_symlink("/proc/self/exe", ec);
        if (!ec) candidates.push_back((exe.parent_path() / RENDER_IMAGE_PLUGIN_FILE).string());
#ifdef RENDER_IMAGE_PLUGIN_BUILD_DIR
        candidates.push_back(std::string(RENDER_IMAGE_PLUGIN_BUILD_DIR) + "/" +
                             RENDER_IMAGE_PLUGIN_FILE);
#endif
        candidates.push_back(RENDER_IMAGE_PLUGIN_FILE);  // the dynamic loader's search
    }
    for (size_t i = 0; i < candidates.size(); ++i) {
        const std::string& candidate = candidates[i];
        if (std::find(candidates.begin(), candidates.begin() + long(i), candidate) !=
            candidates.begin() + long(i))
            continue;  // the executable's folder is the build tree's bin/
        const bool bare = candidate.find('/') == std::string::npos;
        std::error_code ec;
        if (!bare && !std::filesystem::exists(candidate, ec)) {
            *failures += "\n  " + candidate + ": no such file";
            continue;
        }
        // Lazy binding, as for the libraries of an executable: RTLD_NOW would resolve every
        // symbol of OpenImageIO's ~250 libraries up front.
        void* handle = dlopen(candidate.c_str(), RTLD_LAZY | RTLD_LOCAL);
        if (!handle) {
            const char* message = dlerror();
            *failures += "\n  " + candidate + ": " + (message ? message : "cannot be loaded");
            continue;
        }
        auto entry =
            reinterpret_cast<RenderImagePluginEntry>(dlsym(handle, RENDER_IMAGE_PLUGIN_ENTRY));
        const RenderImagePlugin* plugin = entry ? entry() : nullptr;
        if (!plugin || plugin->version != RENDER_IMAGE_PLUGIN_VERSION || !plugin->read ||
            !plugin->write_rgb8) {
            *failures += "\n  " + candidate + ": not a version " +
                         std::to_string(RENDER_IMAGE_PLUGIN_VERSION) + " image plugin (" +
                         RENDER_IMAGE_PLUGIN_ENTRY + ")";
            dlclose(handle);
            continue;
        }
        return plugin;  // kept loaded for the life of the process
    }
    return nullptr;
}

}  // namespace

const RenderImagePlugin& image_plugin(const std::string& purpose) {
    struct Loaded {
        const RenderImagePlugin* plugin = nullptr;
        std::string failures;
    };
    static const Loaded loaded = [] {
        Loaded l;
        l.plugin = load_plugin(&l.failures);
        return l;
    }();
    if (!loaded.plugin)
        throw std::runtime_error(
            std::string("the image plugin " RENDER_IMAGE_PLUGIN_FILE " (OpenImageIO), needed ") +
            purpose +
            ", cannot be loaded (set RENDER_IMAGE_PLUGIN to its path); tried:" + loaded.failures);
    return *loaded.plugin;
}

}  // namespace render
