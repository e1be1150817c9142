#pragma once

// Algorithm lists for parameterised tests, taken from the algorithm table
// (core/render/algorithms.cpp): a new physically based algorithm, or a variant selected by
// options, joins the furnace and iteration-contract tests without editing them.

#include <string>
#include <vector>

#include "core/render/algorithms.h"
#include "core/render/render_options.h"
#include "core/scene/scene.h"

namespace render::testing {

// Every algorithm that converges to the scene's image (all but debug shading), in table order,
// each followed by its variants written "name option=value,option=value".
inline std::vector<std::string> physically_based_algorithms() {
    std::vector<std::string> names;
    for (const Algorithm& a : algorithms()) {
        if (!a.physically_based) continue;
        names.push_back(a.name);
        for (const auto& variant : a.variants) {
            std::string name = a.name;
            char separator = ' ';
            for (const auto& [option, value] : variant) {
                name += separator + option + "=" + value;
                separator = ',';
            }
            names.push_back(name);
        }
    }
    return names;
}

// The default settings of an entry of physically_based_algorithms() (name and options).
inline RenderSettings algorithm_settings(const std::string& entry) {
    const size_t space = entry.find(' ');
    OptionMap options;
    if (space != std::string::npos) {
        size_t begin = space + 1;
        while (begin < entry.size()) {
            size_t end = entry.find(',', begin);
            if (end == std::string::npos) end = entry.size();
            const std::string pair = entry.substr(begin, end - begin);
            const size_t equals = pair.find('=');
            options[pair.substr(0, equals)] = pair.substr(equals + 1);
            begin = end + 1;
        }
    }
    return resolve_render_settings(entry.substr(0, space), options, SceneSettings{});
}

}  // namespace render::testing
