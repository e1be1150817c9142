#include "core/base/dynamic_plugin.h"

#include <dlfcn.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <vector>

namespace render {

const void* load_dynamic_plugin(
    const DynamicPluginSpec& spec,
    const std::function<const void*(void* entry, std::string* why)>& accept,
    std::string* failures) {
    std::vector<std::string> candidates;
    const char* forced = std::getenv(spec.environment);
    if (forced && *forced) {
        candidates.push_back(forced);
    } else {
        std::error_code ec;
        std::filesystem::path exe = std::filesystem::read_symlink("/proc/self/exe", ec);
        if (!ec) candidates.push_back((exe.parent_path() / spec.file).string());
#ifdef RENDER_PLUGIN_BUILD_DIR
        candidates.push_back(std::string(RENDER_PLUGIN_BUILD_DIR) + "/" + spec.file);
#endif
        candidates.push_back(spec.file);  // the dynamic loader's search
    }
    for (size_t i = 0; i < candidates.size(); ++i) {
        const std::string& candidate = candidates[i];
        if (std::find(candidates.begin(), candidates.begin() + long(i), candidate) !=
            candidates.begin() + long(i))
            continue;  // the executable's folder is the build tree's bin/
        const bool bare = candidate.find('/') == std::string::npos;
        std::error_code ec;
        if (!bare && !std::filesystem::exists(candidate, ec)) {
            *failures += "\n  " + candidate + ": no such file";
            continue;
        }
        // Lazy binding, as for the libraries of an executable: RTLD_NOW would resolve every
        // symbol of the plugin's dependencies up front.
        void* handle = dlopen(candidate.c_str(), RTLD_LAZY | RTLD_LOCAL);
        if (!handle) {
            const char* message = dlerror();
            *failures += "\n  " + candidate + ": " + (message ? message : "cannot be loaded");
            continue;
        }
        std::string why;
        const void* accepted = accept(dlsym(handle, spec.entry), &why);
        if (!accepted) {
            *failures += "\n  " + candidate + ": " + why;
            dlclose(handle);
            continue;
        }
        return accepted;  // kept loaded for the life of the process
    }
    return nullptr;
}

}  // namespace render
