// Fuzz target: the PLY reader (ASCII and both binary encodings) on bytes in memory. Every input
// either gives a mesh or is refused with a SceneError.

#include <cstddef>
#include <cstdint>
#include <string_view>

#include "core/base/error.h"
#include "core/mesh_io/ply_reader.h"
#include "tests/fuzz/fuzz_files.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    render::fuzz::quiet_warnings();
    try {
        render::read_ply_from_memory(std::string_view(reinterpret_cast<const char*>(data), size),
                                     "fuzz.ply");
    } catch (const render::SceneError& e) {
        render::fuzz::refused(e);
    }
    return 0;
}
