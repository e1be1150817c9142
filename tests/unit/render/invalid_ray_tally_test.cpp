// Invalid rays are counted per render (core/render/arena_invalid_ray_tally.h): two renders of
// one scene at once in one process, each in its own task arena, each count exactly their own
// rays the scene's guard kept from Embree, while the scene counts them all; a render with no
// invalid ray reports none.

#include <gtest/gtest.h>

#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <cmath>
#include <string>
#include <thread>

#include "core/render/arena_invalid_ray_tally.h"
#include "core/render/render_iterations.h"
#include "core/scene/loader/scene_loader.h"

namespace render {
namespace {

const std::string kScene = std::string(RENDER_SOURCE_DIR) + "/scenes/smallvcm/1-glm_c.xml";

// In `arena`, `n` closest-hit and `n` occlusion queries, with a NaN ray every `every`-th query
// and valid camera rays otherwise, spread over the arena's threads; returns the arena's tally.
uint64_t trace_in_arena(const Scene& scene, tbb::task_arena& arena, int n, int every) {
    ArenaInvalidRayTally tally(arena);
    arena.execute([&] {
        tbb::parallel_for(0, n, [&](int i) {
            const Ray valid = scene.camera().generate_ray(Vec2(0.5f + float(i % 7), 0.5f));
            const Ray ray = i % every == 0 ? Ray(Vec3(NAN, 0, 0), Vec3(0, 0, 1)) : valid;
            SurfaceInteraction si;
            scene.intersect(ray, si);
            scene.occluded(ray);
        });
    });
    return tally.count();
}

TEST(InvalidRayTally, TwoRendersAtOnceEachCountTheirOwnRays) {
    const auto scene = load_scene(kScene);
    const uint64_t before = scene->invalid_rays();
    // n queries with every `every`-th invalid: 2 * ceil(n / every) invalid rays.
    constexpr int n = 20000;
    uint64_t a = 0, b = 0;
    std::thread first([&] {
        tbb::task_arena arena(2);
        a = trace_in_arena(*scene, arena, n, 3);
    });
    std::thread second([&] {
        tbb::task_arena arena(2);
        b = trace_in_arena(*scene, arena, n, 10);
    });
    first.join();
    second.join();
    EXPECT_EQ(a, uint64_t(2 * ((n + 2) / 3)));
    EXPECT_EQ(b, uint64_t(2 * ((n + 9) / 10)));
    EXPECT_EQ(scene->invalid_rays() - before, a + b);
}

TEST(InvalidRayTally, AThreadOutsideEveryObservedArenaCountsIntoNone) {
    const auto scene = load_scene(kScene);
    tbb::task_arena arena(1);
    EXPECT_EQ(trace_in_arena(*scene, arena, 10, 1), 20u);
    // This thread left the arena: its invalid rays reach the scene's count alone.
    const uint64_t before = scene->invalid_rays();
    SurfaceInteraction si;
    scene->intersect(Ray(Vec3(0, 0, 0), Vec3(NAN, 0, 1)), si);
    EXPECT_EQ(scene->invalid_rays() - before, 1u);
    tbb::task_arena other(1);
    EXPECT_EQ(trace_in_arena(*scene, other, 4, 2), 4u);
}

TEST(InvalidRayTally, ARenderOfAValidSceneCountsNone) {
    const auto scene = load_scene(kScene);
    RenderSettings settings;
    settings.algorithm = "pt";
    settings.threads = 2;
    const IterationResult result = render_iterations(*scene, settings, 0, {1, 3});
    EXPECT_EQ(result.count, 2u);
    EXPECT_EQ(result.stats.invalid_rays, 0u);
}

}  // namespace
}  // namespace render
