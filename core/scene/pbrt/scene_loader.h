#pragma once

// Loads a pbrt-v4 scene file (.pbrt) into the same Scene the Mitsuba loader builds. The
// accepted directives, plugins and parameters: docs/reference/scene-format.md, "pbrt-v4 scenes".

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

// A pbrt integrator as the scene records it: "pbrt:NAME". The algorithm table maps it
// (Algorithm::pbrt_integrators: bdpt is bpt, sppm is ppm, ...); a name no row has needs --algo,
// as a Mitsuba integrator that names no algorithm does.
std::string integrator_name(const std::string& pbrt_name);

// What the client's bundle needs of a pbrt scene, read without building it.
struct SceneSummary {
    // Every file the scene reads (Include/Import files, "string filename" parameters but
    // Film's), resolved as the loader resolves them (relative to the main scene's folder),
    // without the scene itself.
    std::vector<std::filesystem::path> files;
    std::string integrator;       // as the loader names it ("volpath" when the file has none)
    long long sample_count = 16;  // the Sampler's pixel samples (pbrt's default 16)
};
// Throws SceneError for unreadable files or a malformed file.
SceneSummary summarize(const std::filesystem::path& file);

}  // namespace render::pbrt
