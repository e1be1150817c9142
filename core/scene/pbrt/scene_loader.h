#pragma once

// Loads a pbrt-v4 scene file (.pbrt) into the same Scene the Mitsuba loader builds. The
// accepted directives, plugins and parameters: docs/scene-format.md, "pbrt-v4 scenes".

#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "core/scene/scene.h"

namespace render::pbrt {

// As render::load_scene: a non-empty `confine_to` is the only folder the scene may read from.
// Throws SceneError naming file, line and directive or parameter.
std::unique_ptr<Scene> load_scene(const std::filesystem::path& file,
                                  const std::filesystem::path& confine_to = {});

// From a string (tests); relative file names resolve against base_dir.
std::unique_ptr<Scene> load_scene_from_string(const std::string& text,
                                              const std::filesystem::path& base_dir);

// Every file a pbrt scene reads (Include/Import files, "string filename" parameters), resolved
// as the loader resolves them (relative to the main scene's folder), without the scene itself.
// For the client's bundle. Throws SceneError for unreadable files or a malformed file.
std::vector<std::filesystem::path> referenced_files(const std::filesystem::path& file);

}  // namespace render::pbrt
