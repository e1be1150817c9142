#pragma once

// Mitsuba's file resolution for `<include filename>` and every `filename` parameter: a relative
// name is looked up, in this order, in the folder of the file that names it, in the main
// scene's folder, and in every `<path value="..."/>` folder in the order they were declared
// (a relative `<path>` is relative to the main scene's folder). The first candidate that is an
// existing regular file wins; an absolute name is used as it is.
//
// The scene loader and the client's bundle collector (client/bundle.cpp) both resolve through
// this class, so a job carries exactly the files its scene resolves to.
//
// Path confinement (the `confine_to` folder of load_scene) is here too: both scene loaders
// (Mitsuba, core/scene/loader, and pbrt, core/scene/pbrt) check their files with
// FolderConfinement, so the two refuse a file outside the job's folder with the same message.

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace render {

class FileResolver {
  public:
    explicit FileResolver(std::filesystem::path scene_dir);

    const std::filesystem::path& scene_dir() const { return scene_dir_; }

    // The folder a `<path value>` names: `value` itself when absolute, else relative to the
    // main scene's folder (lexically normalised).
    std::filesystem::path search_folder(const std::filesystem::path& value) const;
    // Appends a search folder (as returned by search_folder()).
    void add_search_path(const std::filesystem::path& folder);
    const std::vector<std::filesystem::path>& search_paths() const { return search_paths_; }

    // Every place `name` is looked for, in order (just `name` when it is absolute), each
    // lexically normalised.
    std::vector<std::filesystem::path> candidates(const std::filesystem::path& name,
                                                  const std::filesystem::path& naming_dir) const;
    // The first candidate that is a regular file; nothing when there is none.
    std::optional<std::filesystem::path> resolve(const std::filesystem::path& name,
                                                 const std::filesystem::path& naming_dir) const;

  private:
    std::filesystem::path scene_dir_;
    std::vector<std::filesystem::path> search_paths_;
};

// `p` with symbolic links resolved (std::filesystem::weakly_canonical); the absolute, lexically
// normalised `p` when that fails.
std::filesystem::path canonical_path(const std::filesystem::path& p);

// The only folder a scene may read from. A non-empty `folder` (a loader's `confine_to`)
// confines: every included file, every plugin's file and every search folder must lie inside
// it after resolving symbolic links. An empty one confines nothing.
class FolderConfinement {
  public:
    explicit FolderConfinement(const std::filesystem::path& folder);

    // True when `path` (a file or a folder) lies outside the folder; never when unconfined.
    bool outside(const std::filesystem::path& path) const;
    // "PATH is outside FOLDER (a job reads only the files of its bundle)": the refusal both
    // loaders report (after their own prefix) for a path outside() is true of.
    std::string outside_message(const std::filesystem::path& path) const;

  private:
    bool confined_ = false;
    std::filesystem::path root_;
};

}  // namespace render
