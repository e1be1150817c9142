#pragma once

// An empty folder for one test: under the temporary directory, named after the test file's
// `prefix`, the test's `name` and the process (tests of one binary may run in parallel
// processes under CTest). Emptied if a previous run left it.

#include <unistd.h>

#include <filesystem>
#include <string>

namespace render::testing {

inline std::filesystem::path fresh_temp_dir(const std::string& prefix, const std::string& name) {
    const std::filesystem::path dir = std::filesystem::temp_directory_path() /
                                      (prefix + "_" + name + "_" + std::to_string(::getpid()));
    std::filesystem::remove_all(dir);
    std::filesystem::create_directories(dir);
    return dir;
}

}  // namespace render::testing
