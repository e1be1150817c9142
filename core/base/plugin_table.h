#pragma once

// The registry form every plugin kind uses (Mitsuba 3's): a table of {scene-file name, factory}
// rows in the kind's factory file. The loader's "unknown ... type (supported: ...)" message is
// derived from the table, so a new plugin is its own file plus one row.

#include <string>

#include "core/base/error.h"
#include "core/base/properties.h"

namespace render {

template <typename Factory>
struct Plugin {
    const char* name;
    Factory create;
};

// The row named props.type(); a SceneError at the element's location otherwise, e.g.
// `unknown bsdf type "velvet" (supported: diffuse, ...)` for kind "bsdf".
template <typename Factory, size_t N>
const Plugin<Factory>& find_plugin(const Plugin<Factory> (&table)[N], const Properties& props,
                                   const char* kind) {
    for (const Plugin<Factory>& plugin : table)
        if (props.type() == plugin.name) return plugin;
    std::string supported;
    for (const Plugin<Factory>& plugin : table)
        supported += std::string(supported.empty() ? "" : ", ") + plugin.name;
    throw SceneError(props.where(), std::string("unknown ") + kind + " type \"" + props.type() +
                                        "\" (supported: " + supported + ")");
}

}  // namespace render
