#include "core/image/image_plugin.h"

#include <stdexcept>

#include "core/base/dynamic_plugin.h"

namespace render {

const RenderImagePlugin& image_plugin(const std::string& purpose) {
    struct Loaded {
        const RenderImagePlugin* plugin = nullptr;
        std::string failures;
    };
    static const Loaded loaded = [] {
        Loaded l;
        const DynamicPluginSpec spec{RENDER_IMAGE_PLUGIN_FILE, "RENDER_IMAGE_PLUGIN",
                                     RENDER_IMAGE_PLUGIN_ENTRY};
        l.plugin = static_cast<const RenderImagePlugin*>(load_dynamic_plugin(
            spec,
            [](void* entry, std::string* why) -> const void* {
                const RenderImagePlugin* plugin =
                    entry ? reinterpret_cast<RenderImagePluginEntry>(entry)() : nullptr;
                if (plugin && plugin->version == RENDER_IMAGE_PLUGIN_VERSION && plugin->read &&
                    plugin->write_rgb8)
                    return plugin;
                *why = "not a version " + std::to_string(RENDER_IMAGE_PLUGIN_VERSION) +
                       " image plugin (" RENDER_IMAGE_PLUGIN_ENTRY ")";
                return nullptr;
            },
            &l.failures));
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
