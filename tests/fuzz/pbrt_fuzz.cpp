// Fuzz target: the pbrt-v4 scene loader (core/scene/pbrt/), with Include/Import files and
// meshes written beside the scene (tests/fuzz/fuzz_files.h), confined to the input's folder as
// on the server. Every input either loads or is refused with a SceneError, and a scene that
// loads passes probe_scene (scene_probe.h: finite, traceable camera rays).

#include <cstddef>
#include <cstdint>

#include "core/base/error.h"
#include "core/scene/pbrt/scene_loader.h"
#include "tests/fuzz/fuzz_files.h"
#include "tests/fuzz/scene_probe.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    render::fuzz::quiet_warnings();
    const auto scene = render::fuzz::write_fuzz_files(data, size, "scene.pbrt");
    try {
        render::fuzz::probe_scene(*render::pbrt::load_scene(scene, scene.parent_path()));
    } catch (const render::SceneError& e) {
        render::fuzz::refused(e);
    }
    return 0;
}
