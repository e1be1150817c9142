// Scene::occluded queries its own BVH (built without Embree's ROBUST flag, core/scene/scene.cpp)
// while Scene::intersect and closest_hit_distance query the ROBUST one. Both hold the same
// geometries, so a segment must be blocked exactly when the closest hit lies before its end,
// on every kind of geometry (triangles, analytic spheres, rectangles, instances), whether
// occluded() tests the analytic shapes itself (at most four of them: the boxes, veach-mis) or
// through its BVH (more than four: the scene of six spheres below; those of instanced groups).
//
// Random segments (fixed seeds) from points in the scene's bounds: the closest hit along the
// whole ray is t_hit, and the segment ends at t_max = t_hit * (0.5 + u), u uniform in [0, 1),
// or anywhere within the scene's diameter when the ray hits nothing. A segment whose end lies
// within 1e-4 * t_hit of the hit is skipped: there the answer is decided by rounding, which
// the two BVHs round differently. Tolerance: the two BVHs also round differently for a ray
// through a triangle's edge or a BVH box's face, which in renders happened to between 0 and
// 1.3e-5 of the shadow rays (docs/results/performance-notes.md, "Shadow rays through their own
// BVH"); at most 1e-4 of the segments may disagree, 8 times that measured rate.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <memory>
#include <string>
#include <vector>

#include "core/base/memory_budget.h"
#include "core/sampling/rng.h"
#include "core/sampling/warp.h"
#include "core/scene/embree_ray.h"
#include "core/scene/loader/scene_loader.h"
#include "core/scene/scene.h"
#include "core/shapes/sphere.h"
#include "core/shapes/triangle_mesh.h"

namespace render {
namespace {

struct Agreement {
    int tested = 0, blocked = 0, disagreements = 0;
    // The batched Scene::occluded against the single-ray one on the same rays.
    int batch_disagreements = 0;
};

Agreement compare_occlusion_with_closest_hits(const Scene& scene, uint64_t seed, int segments) {
    Rng rng(StreamKey{.seed = seed, .iteration = 1, .stream = 0});
    const Aabb box = scene.bounds();
    const float diameter = 2 * scene.bounding_sphere().radius;
    Agreement a;
    std::vector<Ray> rays;
    std::vector<char> single;
    for (int i = 0; i < segments; ++i) {
        const Vec3 u = rng.next_3d();
        const Vec3 origin = box.lo + (box.hi - box.lo) * u;
        const Vec3 direction = warp::square_to_uniform_sphere(rng.next_2d());
        const float t_hit = scene.closest_hit_distance(Ray(origin, direction, 0.0f, kInfinity));
        const float t_max =
            std::isinf(t_hit) ? diameter * rng.next_1d() : t_hit * (0.5f + rng.next_1d());
        if (!(t_max > 0) || (std::isfinite(t_hit) && std::abs(t_max - t_hit) <= 1e-4f * t_hit))
            continue;
        const bool expected = t_hit < t_max;
        const bool occluded = scene.occluded(Ray(origin, direction, 0.0f, t_max));
        rays.push_back(Ray(origin, direction, 0.0f, t_max));
        single.push_back(occluded ? 1 : 0);
        ++a.tested;
        a.blocked += expected ? 1 : 0;
        a.disagreements += occluded != expected ? 1 : 0;
    }
    // In uneven batches (1 to 100 rays), so that a partly filled stream call is covered too.
    std::unique_ptr<bool[]> batched(new bool[rays.size()]);
    for (size_t start = 0, n = 1; start < rays.size(); start += n, n = n % 100 + 1)
        scene.occluded(rays.data() + start, std::min(n, rays.size() - start),
                       batched.get() + start);
    for (size_t i = 0; i < rays.size(); ++i)
        a.batch_disagreements += (batched[i] ? 1 : 0) != single[i] ? 1 : 0;
    return a;
}

class OcclusionAgreesWithClosestHit : public testing::TestWithParam<std::string> {};

TEST_P(OcclusionAgreesWithClosestHit, AlongRandomSegments) {
    const auto scene = load_scene(std::string(RENDER_SOURCE_DIR) + "/scenes/" + GetParam());
    constexpr int kSegments = 100000;
    const Agreement a = compare_occlusion_with_closest_hits(*scene, 20261127, kSegments);
    // Most segments are tested, and both answers occur often: the comparison is not vacuous.
    EXPECT_GT(a.tested, kSegments * 9 / 10);
    EXPECT_GT(a.blocked, a.tested / 10);
    EXPECT_LT(a.blocked, a.tested * 9 / 10);
    EXPECT_LE(a.disagreements, a.tested / 10000)
        << a.disagreements << " of " << a.tested << " segments";
    // Embree's stream traversal may round differently from its single-ray one only for a ray
    // through an edge: at most 1 in 10,000, as above.
    EXPECT_LE(a.batch_disagreements, a.tested / 10000)
        << a.batch_disagreements << " of " << a.tested << " segments (batched)";
    std::printf("%s: %d segments, %d blocked, %d disagreements, %d batched\n", GetParam().c_str(),
                a.tested, a.blocked, a.disagreements, a.batch_disagreements);
}

// More analytic shapes than occluded() tests itself: all of them go through the BVH.
TEST(Occlusion, SixSpheresInTheBvhAgreeWithClosestHits) {
    Scene scene;
    scene.set_camera(PerspectiveCamera(Transform(), 45, 'x', 4, 4));
    Rng rng(StreamKey{.seed = 7, .iteration = 1, .stream = 0});
    for (int i = 0; i < 6; ++i) {
        // Appended, not "s" + std::to_string(i): GCC 12 warns falsely (-Wrestrict) on that.
        std::string name = "s";
        name += std::to_string(i);
        scene.add_shape(
            std::make_unique<Sphere>(rng.next_3d() * 4.0f, 0.3f + rng.next_1d(), false, name),
            nullptr);
    }
    scene.commit();
    const Agreement a = compare_occlusion_with_closest_hits(scene, 20261127, 100000);
    EXPECT_GT(a.tested, 90000);
    EXPECT_GT(a.blocked, a.tested / 10);
    EXPECT_EQ(a.disagreements, 0);
    EXPECT_EQ(a.batch_disagreements, 0);
}

// A wavy grid of quads on [0, 4]^2 (two triangles each), n x n quads, and two spheres: a
// scene whose shadow rays see triangles and analytic shapes.
std::unique_ptr<Scene> wavy_grid_scene(int n) {
    MeshData data;
    for (int j = 0; j <= n; ++j)
        for (int i = 0; i <= n; ++i) {
            const float x = 4.0f * float(i) / float(n), y = 4.0f * float(j) / float(n);
            data.positions.push_back(Vec3(x, y, 0.3f * std::sin(3 * x) * std::cos(2 * y)));
        }
    for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i) {
            const uint32_t a = uint32_t(j * (n + 1) + i), b = a + 1, c = a + uint32_t(n + 1),
                           d = c + 1;
            data.indices.insert(data.indices.end(), {a, b, d, a, d, c});
        }
    auto scene = std::make_unique<Scene>();
    scene->set_camera(PerspectiveCamera(Transform(), 45, 'x', 4, 4));
    scene->add_shape(
        std::make_unique<TriangleMesh>(std::move(data), Transform(), false, false, "grid"),
        nullptr);
    scene->add_shape(std::make_unique<Sphere>(Vec3(1, 1, 0.5f), 0.4f, false, "a"), nullptr);
    scene->add_shape(std::make_unique<Sphere>(Vec3(3, 2, 0.2f), 0.6f, false, "b"), nullptr);
    return scene;
}

// The shadow rays' BVH is built, and charged to the scene's memory, only up to
// Scene::kMaxShadowBvhTriangles top-level triangles; a larger scene sends its shadow rays through
// the closest-hit BVH (every analytic shape in it) and is charged nothing more. Both agree with
// the closest hits.
TEST(Occlusion, TheShadowRaysBvhIsBuiltAndChargedOnlyForSmallScenes) {
    for (const int n : {64, 725}) {
        const uint64_t triangles = 2 * uint64_t(n) * uint64_t(n);
        const bool small = triangles <= Scene::kMaxShadowBvhTriangles;
        auto scene = wavy_grid_scene(n);
        SceneMemoryBudget budget(0, "test");
        scene->commit();
        EXPECT_EQ(budget.charged(), small ? Scene::kShadowBvhBytesPerTriangle * triangles : 0)
            << triangles << " triangles";
        const Agreement a = compare_occlusion_with_closest_hits(*scene, 20261127, 20000);
        EXPECT_GT(a.tested, 18000);
        EXPECT_GT(a.blocked, a.tested / 10);
        EXPECT_LE(a.disagreements, a.tested / 10000) << triangles << " triangles";
    }
}

// embree_accepts at its boundaries, float by float: each of the ray's eight floats set in turn to
// the largest accepted value, the next float beyond it, their negatives, infinities and NaN
// (the origin and direction accept |x| <= kMaxSceneCoordinate; t_min and t_max anything but NaN).
TEST(Occlusion, RayGuardBoundaryPerFloat) {
    const float o = kMaxSceneCoordinate, inf = INFINITY, nan = std::nanf("");
    const float beyond = std::nextafter(o, inf);
    for (int i = 0; i < 8; ++i) {
        const bool is_t = i >= 6;
        const struct {
            float value;
            bool accepted;
        } cases[] = {{0.0f, true},    {o, true},   {-o, true},   {beyond, is_t},
                     {-beyond, is_t}, {inf, is_t}, {-inf, is_t}, {nan, false}};
        for (const auto& c : cases) {
            float v[8] = {1, 2, 3, 0, 0, -1, 0, inf};
            v[i] = c.value;
            Ray ray;
            std::memcpy(&ray, v, sizeof v);
            EXPECT_EQ(embree_accepts(ray), c.accepted) << "float " << i << " = " << c.value;
        }
    }
}

// Rays Embree would abort on (embree_accepts, core/scene/embree_ray.h) never reach it: each
// query answers a miss (unoccluded) and counts the ray; valid rays, far ones too, are traced.
TEST(Occlusion, InvalidRaysAreMissesAndCounted) {
    auto scene = wavy_grid_scene(8);
    scene->commit();
    const float nan = std::nanf(""), inf = INFINITY;
    const Vec3 down(0, 0, -1), above(1, 1, 2);
    const Ray invalid[] = {Ray(Vec3(nan, 1, 2), down), Ray(above, Vec3(0, inf, -1)),
                           Ray(Vec3(1, 1, 2e12f), down), Ray(above, down, 0.0f, nan),
                           Ray(above, Vec3(0, 0, -3e12f))};
    uint64_t expected = 0;
    for (const Ray& ray : invalid) {
        SurfaceInteraction si;
        EXPECT_FALSE(scene->intersect(ray, si));
        EXPECT_EQ(scene->closest_hit_distance(ray), kInfinity);
        EXPECT_FALSE(scene->occluded(ray));
        expected += 3;
        EXPECT_EQ(scene->invalid_rays(), expected);
    }
    for (const Ray& ray : {Ray(above, down), Ray(Vec3(1, 1, 9e11f), down)}) {
        SurfaceInteraction si;
        EXPECT_TRUE(scene->intersect(ray, si));
        EXPECT_LT(scene->closest_hit_distance(ray), kInfinity);
        EXPECT_TRUE(scene->occluded(ray));
    }
    EXPECT_EQ(scene->invalid_rays(), expected);
}

INSTANTIATE_TEST_SUITE_P(Scenes, OcclusionAgreesWithClosestHit,
                         testing::Values("smallvcm/0-gbs_s.xml", "smallvcm/1-glm_c.xml",
                                         "smallvcm/2-gbs_p.xml",
                                         "bitterli/cornell-box/scene_v3.xml",
                                         "bitterli/veach-bidir/scene_v3.xml",
                                         "bitterli/veach-mis/scene_v3.xml", "tests/instances.xml",
                                         "tests/instances-flat.xml"),
                         [](const testing::TestParamInfo<std::string>& info) {
                             std::string name;
                             for (char c : info.param)
                                 if (std::isalnum(static_cast<unsigned char>(c))) name += c;
                             return name;
                         });

}  // namespace
}  // namespace render
