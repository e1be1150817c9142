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

// upbp's photon beams and query beams from every light path (--photon-beam-paths 1
// --query-beam-paths 1) where `options` name no fraction. render's defaults keep 1 % of the
// paths' beams and photons (the fraction the measured sweep chose, docs/design/media.md); the
// tests calibrated with every path (furnaces on a few hundred paths, block tests against a
// reference, estimators isolated) ask for all of them explicitly.
inline void beams_from_every_path(RenderSettings& s, const OptionMap& options = {}) {
    if (!options.count("photon_beam_paths")) s.photon_beam_paths = 1;
    if (!options.count("query_beam_paths")) s.query_beam_paths = 1;
}

// The default settings of an entry of physically_based_algorithms() (name and options), upbp's
// beams from every light path unless the entry names a fraction (beams_from_every_path).
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
    RenderSettings settings =
        resolve_render_settings(entry.substr(0, space), options, SceneSettings{});
    beams_from_every_path(settings, options);
    return settings;
}

}  // namespace render::testing
