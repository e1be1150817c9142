// Fuzz target: Mitsuba's binary .vol grid reader and its value check on bytes in memory. Every
// input either gives a grid or is refused with a SceneError; a grid it gives holds exactly the
// voxels its header announces.

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <vector>

#include "core/base/error.h"
#include "core/media/vol_file.h"
#include "tests/fuzz/fuzz_files.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    render::fuzz::quiet_warnings();
    try {
        const render::VolumeGridData grid =
            render::parse_vol(std::vector<unsigned char>(data, data + size), "fuzz.vol");
        if (grid.values.size() != grid.voxel_count() * size_t(grid.channels)) std::abort();
        render::check_volume_values(grid, "fuzz.vol");
    } catch (const render::SceneError& e) {
        render::fuzz::refused(e);
    }
    return 0;
}
