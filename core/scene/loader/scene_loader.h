#pragma once

// Loads a scene in the Mitsuba 3 XML format (the documented subset in docs/scene-format.md).

#include <filesystem>
#include <map>
#include <memory>
#include <string>

#include "core/scene/scene.h"

namespace render {

// `defines` override the file's <default> values (the command line's -D name=value).
// Returns a committed scene. Throws SceneError naming file, line and field for any bad input
// (malformed XML, unknown tag/attribute/plugin, unused parameter, missing file, NaN values...).
std::unique_ptr<Scene> load_scene(const std::filesystem::path& file,
                                  const std::map<std::string, std::string>& defines = {});

// The same from a string (for tests); relative file names resolve against base_dir.
std::unique_ptr<Scene> load_scene_from_string(
    const std::string& xml, const std::filesystem::path& base_dir,
    const std::map<std::string, std::string>& defines = {});

}  // namespace render
