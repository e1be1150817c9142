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

}  // namespace render
