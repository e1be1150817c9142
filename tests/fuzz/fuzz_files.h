#pragma once

// Helpers of the fuzz targets (tests/fuzz/*_fuzz.cpp).
//
// A scene fuzz input may hold several files: the main file's text, then each further file
// after a line "@@@ NAME" (NAME relative, letters, digits and . _ - /, no ".." part), e.g.
//
//     <scene version="3.0.0"> <include filename="inc/a.xml"/> </scene>
//     @@@ inc/a.xml
//     <scene version="3.0.0"> ... </scene>
//
// write_fuzz_files() writes them into a fresh folder of this process (emptied on every call)
// and returns the main file's path, so that includes, meshes and grids are read as the loaders
// read them in production (resolution, confinement, file sizes).

#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <string>
#include <string_view>

namespace render::fuzz {

inline bool safe_fuzz_name(std::string_view name) {
    if (name.empty() || name.size() > 64 || name.front() == '/') return false;
    for (char c : name)
        if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '.' || c == '_' || c == '-' ||
              c == '/'))
            return false;
    for (const auto& part : std::filesystem::path(name))
        if (part == ".." || part == ".") return false;
    return true;
}

// The folder the inputs are written to: one per process, below the system's temp folder,
// removed when the process exits normally (libFuzzer's -max_total_time, the replay's end).
inline std::filesystem::path process_fuzz_folder() {
    return std::filesystem::temp_directory_path() / ("render_fuzz_" + std::to_string(::getpid()));
}
inline const std::filesystem::path& fuzz_folder() {
    static const std::filesystem::path folder = [] {
        std::atexit([] {
            std::error_code ec;
            std::filesystem::remove_all(process_fuzz_folder(), ec);
        });
        return process_fuzz_folder();
    }();
    return folder;
}

// Writes the input's files (see above) into fuzz_folder()/root/ and returns root/`main_name`.
// Sections with an unsafe name are dropped.
inline std::filesystem::path write_fuzz_files(const uint8_t* data, size_t size,
                                              const std::string& main_name) {
    namespace fs = std::filesystem;
    const fs::path root = fuzz_folder() / "root";
    std::error_code ec;
    fs::remove_all(root, ec);
    fs::create_directories(root);
    const std::string_view text(reinterpret_cast<const char*>(data), size);
    std::string name = main_name;
    size_t begin = 0;
    while (true) {
        const size_t marker = text.find("\n@@@ ", begin);
        const size_t end = marker == std::string_view::npos ? text.size() : marker;
        if (safe_fuzz_name(name)) {
            const fs::path file = root / name;
            fs::create_directories(file.parent_path(), ec);
            std::ofstream(file, std::ios::binary).write(text.data() + begin, long(end - begin));
        }
        if (marker == std::string_view::npos) break;
        const size_t name_begin = marker + 5;
        size_t name_end = text.find('\n', name_begin);
        if (name_end == std::string_view::npos) name_end = text.size();
        name = std::string(text.substr(name_begin, name_end - name_begin));
        begin = std::min(name_end + 1, text.size());
    }
    return root / main_name;
}

// Called with every SceneError a target accepts: prints it when RENDER_FUZZ_VERBOSE is set
// (to see what the seeds reach), else nothing.
inline void refused(const std::exception& e) {
    static const bool verbose = std::getenv("RENDER_FUZZ_VERBOSE") != nullptr;
    if (verbose) std::fprintf(stderr, "  refused: %s\n", e.what());
}

// Silences std::cerr (the loaders' warnings, one per input, would flood a fuzzer's output)
// unless RENDER_FUZZ_VERBOSE is set. The sanitizers and libFuzzer write to fd 2 directly.
inline void quiet_warnings() {
    static const bool once = [] {
        if (!std::getenv("RENDER_FUZZ_VERBOSE")) std::cerr.rdbuf(nullptr);
        return true;
    }();
    (void)once;
}

}  // namespace render::fuzz

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size);
