#pragma once

// The render options a request carries (proto RenderSettings): its generic `options` map,
// validated against the render options table (core/render/render_options.h), with the typed
// fields that older clients set folded in. The server, the worker and the client use these,
// so a new option needs no proto change and no code here.
// No OpenImageIO header may be included next to this one (DEPENDENCIES.md, trap 2).

#include <string>

#include "core/render/render_options.h"
#include "render.pb.h"

namespace render::service {

// The options of `settings`: its map, plus seed, radius_factor, alpha, max_depth and
// light_path_count from the typed fields where those are set (non-zero, has_max_depth) and the
// map lacks them. Values are not checked here. Throws std::invalid_argument when a typed field
// and the map name different values.
OptionMap request_options(const v1::RenderSettings& settings);

// Checks every option's name and value (not yet whether the algorithm reads it: that needs the
// algorithm, which may come from the scene). Returns "" or a message naming the option as
// settings.options["NAME"].
std::string check_request_options(const OptionMap& options);

// Stores `options` as the request's only options: the map is replaced, the typed legacy fields
// are cleared, and the typed seed mirrors options["seed"] for readers of the old field.
void set_request_options(v1::RenderSettings& settings, const OptionMap& options);

}  // namespace render::service
