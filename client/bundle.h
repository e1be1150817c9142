#pragma once

// Packs a scene for submission: the scene file plus every file it references (`<include
// filename>` recursively, and every `filename` property such as meshes and environment maps),
// with paths relative to the scene's folder, hashed for the content-addressed asset store.

#include <cstdint>
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace render::service {

struct BundleEntry {
    std::string path;                // relative to the scene's folder, forward slashes
    std::filesystem::path absolute;  // on this machine
    std::string sha256;
    uint64_t size = 0;
};

struct SceneBundleInfo {
    std::filesystem::path root;  // the scene's folder
    std::string scene_path;      // the scene file, relative to root
    std::vector<BundleEntry> files;
    // What the scene file says (after $name substitution), if it could be read.
    std::string integrator;
    std::optional<uint64_t> sample_count;
};

// Throws std::runtime_error naming the file (and the referencing file) for unreadable or
// malformed XML, a missing file, an undefined $name in a file name, or a file outside the
// scene's folder. Without `hash`, the entries' sha256 and size are left empty (see
// hash_bundle).
SceneBundleInfo collect_bundle(const std::filesystem::path& scene_file,
                               const std::map<std::string, std::string>& defines, bool hash = true);

// Sets the sha256 and size of every entry.
void hash_bundle(SceneBundleInfo& bundle);

}  // namespace render::service
