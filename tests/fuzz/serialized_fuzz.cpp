// Fuzz target: the reader of Mitsuba's serialized meshes (a zlib stream per mesh and an
// end-of-file dictionary) on bytes in memory, for the first and the second mesh. Every input
// either gives a mesh or is refused with a SceneError.

#include <cstddef>
#include <cstdint>
#include <string_view>

#include "core/base/error.h"
#include "core/mesh_io/serialized_reader.h"
#include "tests/fuzz/fuzz_files.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    render::fuzz::quiet_warnings();
    const std::string_view bytes(reinterpret_cast<const char*>(data), size);
    for (size_t index : {size_t(0), size_t(1)}) {
        try {
            render::read_serialized_from_memory(bytes, index, "fuzz.serialized");
        } catch (const render::SceneError& e) {
            render::fuzz::refused(e);
        }
    }
    return 0;
}
