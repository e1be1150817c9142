#pragma once

// Registry from scene-file emitter names ("area", "point", "envmap", ...) to classes.

#include <filesystem>
#include <memory>

#include "core/base/properties.h"
#include "core/base/shape.h"
#include "core/lights/light.h"

namespace render {

// Builds the emitter that props.type() names. `shape` is the shape an `area` emitter is nested
// in (null for a top-level emitter, where `area` is an error). Relative file names (envmap
// `filename`) are resolved against scene_dir. Throws SceneError for bad input.
std::unique_ptr<Light> make_light(const Properties& props, const Shape* shape,
                                  const std::filesystem::path& scene_dir);

}  // namespace render
