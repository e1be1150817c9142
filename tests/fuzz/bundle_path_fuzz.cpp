// Fuzz target: the paths of a job's bundle, on both sides.
//  - The client's collector (client/bundle.cpp, collect_bundle) over a scene written beside
//    its files (tests/fuzz/fuzz_files.h; a .pbrt scene when the input starts with '#', Mitsuba
//    XML otherwise): it either fails with a std::runtime_error, or every file it bundles lies
//    inside the scene's folder and has a path the server accepts (check_bundle_path).
//  - The server's check_bundle_path over the raw input: a path it accepts stays inside the job
//    folder once joined and normalised, and with_bundle_paths leaves no folder prefix behind.

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <stdexcept>
#include <string>

#include "client/bundle.h"
#include "server/validation.h"
#include "service/bundle_paths.h"
#include "tests/fuzz/fuzz_files.h"

namespace fs = std::filesystem;

namespace {

bool inside(const fs::path& folder, const fs::path& file) {
    const fs::path rel = file.lexically_normal().lexically_relative(folder.lexically_normal());
    return !rel.empty() && *rel.begin() != ".." && !rel.is_absolute();
}

void check_server_path(const std::string& path) {
    const fs::path job = "/store/jobs/job-1";
    if (render::server::check_bundle_path(path).empty() && !inside(job, job / path)) std::abort();
    const std::string message =
        render::with_bundle_paths("at " + path + " and " + job.string() + "/" + path, path);
    if (message.find(path + "/") != std::string::npos) std::abort();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    render::fuzz::quiet_warnings();
    check_server_path(std::string(reinterpret_cast<const char*>(data), size));

    const bool pbrt = size > 0 && data[0] == '#';
    const fs::path scene = render::fuzz::write_fuzz_files(data, size, pbrt ? "s.pbrt" : "s.xml");
    try {
        const auto bundle = render::service::collect_bundle(scene, {}, false);
        for (const auto& entry : bundle.files) {
            if (!render::server::check_bundle_path(entry.path).empty()) std::abort();
            if (!inside(scene.parent_path(), entry.absolute)) std::abort();
        }
    } catch (const std::runtime_error& e) {
        render::fuzz::refused(e);
    }
    return 0;
}
