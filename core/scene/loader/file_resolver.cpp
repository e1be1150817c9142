#include "core/scene/loader/file_resolver.h"

#include <algorithm>
#include <system_error>

namespace render {

namespace fs = std::filesystem;

FileResolver::FileResolver(fs::path scene_dir)
    : scene_dir_(scene_dir.empty() ? fs::path(".") : std::move(scene_dir)) {}

fs::path FileResolver::search_folder(const fs::path& value) const {
    return (value.is_absolute() ? value : scene_dir_ / value).lexically_normal();
}

void FileResolver::add_search_path(const fs::path& folder) {
    search_paths_.push_back(folder);
}

std::vector<fs::path> FileResolver::candidates(const fs::path& name,
                                               const fs::path& naming_dir) const {
    if (name.is_absolute()) return {name.lexically_normal()};
    std::vector<fs::path> out;
    auto add = [&](const fs::path& dir) {
        fs::path p = (dir.empty() ? fs::path(".") / name : dir / name).lexically_normal();
        if (std::find(out.begin(), out.end(), p) == out.end()) out.push_back(p);
    };
    add(naming_dir);
    add(scene_dir_);
    for (const fs::path& dir : search_paths_) add(dir);
    return out;
}

std::optional<fs::path> FileResolver::resolve(const fs::path& name,
                                              const fs::path& naming_dir) const {
    for (const fs::path& p : candidates(name, naming_dir)) {
        std::error_code ec;
        if (fs::is_regular_file(p, ec)) return p;
    }
    return std::nullopt;
}

fs::path canonical_path(const fs::path& p) {
    std::error_code ec;
    fs::path c = fs::weakly_canonical(p, ec);
    return ec ? fs::absolute(p).lexically_normal() : c;
}

FolderConfinement::FolderConfinement(const fs::path& folder)
    : confined_(!folder.empty()), root_(confined_ ? canonical_path(folder) : fs::path()) {}

bool FolderConfinement::outside(const fs::path& path) const {
    if (!confined_) return false;
    const std::string rel = canonical_path(path).lexically_relative(root_).generic_string();
    return rel.empty() || rel == ".." || rel.rfind("../", 0) == 0;
}

std::string FolderConfinement::outside_message(const fs::path& path) const {
    return path.string() + " is outside " + root_.string() +
           " (a job reads only the files of its bundle)";
}

}  // namespace render
