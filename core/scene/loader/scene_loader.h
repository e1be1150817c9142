#pragma once

// Loads a scene in the Mitsuba 3 XML format (the documented subset in
// docs/reference/scene-format.md).

#include <filesystem>
#include <map>
#include <memory>
#include <string>

#include "core/scene/scene.h"

namespace render {

// `defines` override the file's <default> values (the command line's -D name=value).
// A non-empty `confine_to` is the only folder the scene may read from: every included file,
// every plugin's file and every <path> folder must lie inside it (after resolving symbolic
// links). The server and the workers pass the job's folder, which holds the job's bundle and
// nothing else a scene should see.
// Returns a committed scene. Throws SceneError naming file, line and field for any bad input
// (malformed XML, unknown tag/attribute/plugin, unused parameter, missing file, NaN values,
// a file outside `confine_to`...).
std::unique_ptr<Scene> load_scene(const std::filesystem::path& file,
                                  const std::map<std::string, std::string>& defines = {},
                                  const std::filesystem::path& confine_to = {});

// The same from a string (for tests); relative file names resolve against base_dir.
std::unique_ptr<Scene> load_scene_from_string(
    const std::string& xml, const std::filesystem::path& base_dir,
    const std::map<std::string, std::string>& defines = {});

}  // namespace render
