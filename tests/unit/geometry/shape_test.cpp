#include <gtest/gtest.h>

#include <cmath>

#include "core/base/error.h"
#include "core/math/constants.h"
#include "core/sampling/rng.h"
#include "core/sampling/warp.h"
#include "core/scene/scene.h"
#include "core/shapes/disk.h"
#include "core/shapes/sphere.h"
#include "core/shapes/triangle_mesh.h"

namespace render {
namespace {

std::unique_ptr<Scene> scene_with(std::unique_ptr<Shape> shape) {
    auto scene = std::make_unique<Scene>();
    scene->set_camera(PerspectiveCamera(Transform(), 45, 'x', 4, 4));
    scene->add_shape(std::move(shape), nullptr);
    scene->commit();
    return scene;
}

TEST(Sphere, HitsFromOutsideAndInside) {
    auto scene = scene_with(std::make_unique<Sphere>(Vec3(1, 2, 3), 0.5f, false, "s"));
    SurfaceInteraction si;
    ASSERT_TRUE(scene->intersect(Ray(Vec3(1, 2, 0), Vec3(0, 0, 1)), si));
    EXPECT_NEAR(si.t, 2.5f, 1e-5f);
    EXPECT_NEAR(si.geometric_normal.z, -1.0f, 1e-5f);
    // From the centre the far side is hit, with the outward normal.
    ASSERT_TRUE(scene->intersect(Ray(Vec3(1, 2, 3), Vec3(0, 1, 0)), si));
    EXPECT_NEAR(si.t, 0.5f, 1e-5f);
    EXPECT_NEAR(si.geometric_normal.y, 1.0f, 1e-5f);
    EXPECT_FALSE(scene->intersect(Ray(Vec3(1, 3, 0), Vec3(0, 0, 1)), si));
    EXPECT_TRUE(scene->occluded(Ray(Vec3(1, 2, 0), Vec3(0, 0, 1), 0, 10)));
    EXPECT_FALSE(scene->occluded(Ray(Vec3(1, 2, 0), Vec3(0, 0, 1), 0, 2.4f)));
}

TEST(Sphere, SampleAreaLiesOnTheSurface) {
    Sphere sphere(Vec3(0, 1, 0), 2.0f, true, "s");
    Rng rng(StreamKey{1, 0, 1, 0});
    for (int i = 0; i < 1000; ++i) {
        ShapeSample s = sphere.sample_area(rng.next_2d());
        EXPECT_NEAR(length(s.p - Vec3(0, 1, 0)), 2.0f, 1e-5f);
        EXPECT_NEAR(dot(s.n, normalize(s.p - Vec3(0, 1, 0))), -1.0f, 1e-5f);  // flipped
        EXPECT_NEAR(s.pdf_area, 1.0f / (16.0f * kPi), 1e-7f);
    }
}

TEST(Disk, HitsInsideTheEllipseOnly) {
    Transform to_world = Transform::translate(Vec3(0, 0, 2)) * Transform::scale(Vec3(2, 1, 1));
    auto disk = std::make_unique<Disk>(to_world, false, "d");
    EXPECT_NEAR(disk->surface_area(), 2.0f * kPi, 1e-5f);
    auto scene = scene_with(std::move(disk));
    SurfaceInteraction si;
    ASSERT_TRUE(scene->intersect(Ray(Vec3(1.9f, 0, 0), Vec3(0, 0, 1)), si));
    EXPECT_NEAR(si.t, 2.0f, 1e-6f);
    EXPECT_NEAR(si.geometric_normal.z, 1.0f, 1e-6f);
    EXPECT_FALSE(scene->intersect(Ray(Vec3(0, 1.1f, 0), Vec3(0, 0, 1)), si));
}

TEST(TriangleMesh, ProceduralShapesHaveMitsubaConventions) {
    TriangleMesh rect(make_rectangle_mesh(), Transform(), false, false, "r");
    EXPECT_NEAR(rect.surface_area(), 4.0f, 1e-6f);
    TriangleMesh cube(make_cube_mesh(), Transform::scale(Vec3(1, 2, 3)), false, false, "c");
    EXPECT_NEAR(cube.surface_area(), 2 * (2 * 4 + 2 * 6 + 4 * 6), 1e-4f);
    // Every cube face samples outward normals.
    Rng rng(StreamKey{2, 0, 1, 0});
    for (int i = 0; i < 1000; ++i) {
        ShapeSample s = cube.sample_area(rng.next_2d());
        EXPECT_GT(dot(s.n, s.p), 0.0f);
    }
}

TEST(TriangleMesh, MirroringTransformKeepsTheNormalOfTheInverseTranspose) {
    // diag(1, 1, -1) mirrors; the rectangle's normal must become -z as Mitsuba's rectangle.
    Transform mirror = Transform::scale(Vec3(1, 1, -1));
    auto rect = std::make_unique<TriangleMesh>(make_rectangle_mesh(), mirror, false, false, "m");
    auto scene = scene_with(std::move(rect));
    SurfaceInteraction si;
    ASSERT_TRUE(scene->intersect(Ray(Vec3(0.2f, 0.3f, 1), Vec3(0, 0, -1)), si));
    EXPECT_NEAR(si.geometric_normal.z, -1.0f, 1e-6f);
    EXPECT_NEAR(si.shading.n.z, -1.0f, 1e-6f);
}

// A rectangle whose four vertex normals all equal `n` (object space), tilted away from its
// face normal so that a hit using the face normal instead would be caught.
MeshData rectangle_with_normals(const Vec3& n) {
    MeshData data = make_rectangle_mesh();
    data.normals.assign(4, n);
    return data;
}

bool orthonormal(const Frame& f) {
    return std::abs(dot(f.s, f.t)) < 1e-6f && std::abs(dot(f.s, f.n)) < 1e-6f &&
           std::abs(dot(f.t, f.n)) < 1e-6f && std::abs(length(f.s) - 1) < 1e-6f &&
           std::abs(length(f.t) - 1) < 1e-6f && std::abs(length(f.n) - 1) < 1e-6f;
}

// Flat-shaded meshes (equal vertex normals on every triangle) keep one shading frame per
// triangle instead of interpolating at each hit (docs/results/performance-notes.md, "mesh hits
// inline, flat-shaded frames"): hits must report the transformed vertex normal (flipped with
// flip_normals) and an orthonormal frame around it, as interpolation did up to rounding.
TEST(TriangleMesh, FlatShadedMeshesReportTheVertexNormalsFrame) {
    const Vec3 object_n = normalize(Vec3(0.3f, -0.2f, 1.0f));
    const Transform to_world = Transform::rotate(normalize(Vec3(1, 2, 3)), 37.0f);
    const Vec3 expected = normalize(to_world.apply_normal(object_n));
    for (bool flip : {false, true}) {
        auto scene = scene_with(std::make_unique<TriangleMesh>(rectangle_with_normals(object_n),
                                                               to_world, flip, false, "flat"));
        const Vec3 centre = to_world.apply_point(Vec3(0, 0, 0));
        const Vec3 face = normalize(to_world.apply_normal(Vec3(0, 0, 1)));
        for (const Vec3 target :
             {Vec3(0.5f, -0.7f, 0), Vec3(-0.9f, 0.8f, 0), Vec3(0.1f, 0.2f, 0)}) {
            const Vec3 p = to_world.apply_point(target);
            SurfaceInteraction si;
            ASSERT_TRUE(scene->intersect(Ray(p + face * 2.0f, face * -1.0f), si));
            const Vec3 want = flip ? -expected : expected;
            EXPECT_NEAR(si.shading.n.x, want.x, 1e-6f) << "flip " << flip;
            EXPECT_NEAR(si.shading.n.y, want.y, 1e-6f) << "flip " << flip;
            EXPECT_NEAR(si.shading.n.z, want.z, 1e-6f) << "flip " << flip;
            EXPECT_TRUE(orthonormal(si.shading));
            EXPECT_NEAR(length(si.p - centre), length(p - centre), 1e-5f);
        }
    }
}

// One vertex normal differing makes the mesh smooth: hits interpolate again.
TEST(TriangleMesh, AMeshWithOneSmoothTriangleInterpolatesItsNormals) {
    MeshData data = rectangle_with_normals(Vec3(0, 0, 1));
    data.normals[2] = normalize(Vec3(1, 0, 1));  // corner (1, 1), shared by both triangles
    auto scene = scene_with(std::make_unique<TriangleMesh>(data, Transform(), false, false, "s"));
    SurfaceInteraction si;
    // Near corner (1, 1) the interpolated normal leans toward +x; at corner (-1, -1) it is +z.
    ASSERT_TRUE(scene->intersect(Ray(Vec3(0.9f, 0.9f, 1), Vec3(0, 0, -1)), si));
    EXPECT_GT(si.shading.n.x, 0.5f);
    EXPECT_TRUE(orthonormal(si.shading));
    ASSERT_TRUE(scene->intersect(Ray(Vec3(-0.99f, -0.99f, 1), Vec3(0, 0, -1)), si));
    EXPECT_LT(si.shading.n.x, 0.01f);
}

// A mesh shaded by its face normals (no vertex normals, or face_normals set) reports the frame
// Frame::from_normal builds around the geometric normal, bit for bit, whether the frame was
// built at load (a small mesh without degenerate triangles: TriangleMesh keeps one per
// triangle), at the hit (a mesh with a degenerate triangle), or at the hit because the mesh is
// larger than the meshes whose frames are kept (a 64 x 64 grid, 8192 triangles). Bit for bit
// because images must not change with where the frame is built.
MeshData grid_mesh(int n) {
    MeshData data;
    for (int y = 0; y <= n; ++y)
        for (int x = 0; x <= n; ++x)
            data.positions.push_back(
                Vec3(2.0f * float(x) / float(n) - 1, 2.0f * float(y) / float(n) - 1, 0));
    for (int y = 0; y < n; ++y)
        for (int x = 0; x < n; ++x) {
            const uint32_t i = uint32_t(y * (n + 1) + x), right = i + 1, up = i + uint32_t(n + 1);
            data.indices.insert(data.indices.end(), {i, right, up + 1, i, up + 1, up});
        }
    return data;
}

TEST(TriangleMesh, FaceNormalMeshesReportTheFrameOfTheGeometricNormal) {
    MeshData with_degenerate = make_rectangle_mesh();
    with_degenerate.indices.insert(with_degenerate.indices.end(), {0, 0, 1});
    const Transform to_world = Transform::rotate(normalize(Vec3(1, 2, 3)), 37.0f);
    const Vec3 face = normalize(to_world.apply_normal(Vec3(0, 0, 1)));
    for (const MeshData& data : {make_rectangle_mesh(), with_degenerate, grid_mesh(64)}) {
        for (bool flip : {false, true}) {
            auto scene =
                scene_with(std::make_unique<TriangleMesh>(data, to_world, flip, true, "faces"));
            for (const Vec3 target :
                 {Vec3(0.5f, -0.7f, 0), Vec3(-0.9f, 0.8f, 0), Vec3(0.1f, 0.2f, 0)}) {
                const Vec3 p = to_world.apply_point(target);
                SurfaceInteraction si;
                ASSERT_TRUE(scene->intersect(Ray(p + face * 2.0f, face * -1.0f), si));
                const Frame want = Frame::from_normal(si.geometric_normal);
                for (int a = 0; a < 3; ++a) {
                    EXPECT_EQ(si.shading.s[a], want.s[a]) << "flip " << flip;
                    EXPECT_EQ(si.shading.t[a], want.t[a]) << "flip " << flip;
                    EXPECT_EQ(si.shading.n[a], want.n[a]) << "flip " << flip;
                }
                // The geometric normal itself: the face's, flipped with flip_normals.
                EXPECT_GT(std::abs(dot(si.geometric_normal, face)), 0.9f);
                EXPECT_GT(dot(si.geometric_normal, face) * (flip ? -1.0f : 1.0f), 0.0f);
            }
        }
    }
}

TEST(TriangleMesh, RejectsBadIndices) {
    MeshData data = make_rectangle_mesh();
    data.indices.push_back(0);
    EXPECT_THROW(TriangleMesh(data, Transform(), false, false, "bad"), SceneError);
    data = make_rectangle_mesh();
    data.indices[2] = 17;
    EXPECT_THROW(TriangleMesh(data, Transform(), false, false, "bad"), SceneError);
}

TEST(TriangleMesh, ZeroAreaTrianglesAreNeverSampled) {
    MeshData data = make_rectangle_mesh();
    data.indices.insert(data.indices.end(), {0, 0, 1});  // degenerate
    TriangleMesh mesh(data, Transform(), false, false, "m");
    Rng rng(StreamKey{3, 0, 1, 0});
    for (int i = 0; i < 10000; ++i) {
        ShapeSample s = mesh.sample_area(rng.next_2d());
        ASSERT_TRUE(is_finite(s.p));
        ASSERT_NEAR(s.n.z, 1.0f, 1e-6f);
    }
}

// Spawned rays neither re-hit their own surface nor tunnel through a close one, whatever the
// scene's scale.
class SpawnScale : public ::testing::TestWithParam<float> {};

TEST_P(SpawnScale, NoSelfIntersectionAndNoTunnelling) {
    const float scale = GetParam();
    auto scene = scene_with(std::make_unique<Sphere>(Vec3(3, -2, 1) * scale, scale, false, "s"));
    Rng rng(StreamKey{4, 0, 1, 0});
    int self_hits = 0, misses = 0;
    for (int i = 0; i < 20000; ++i) {
        ShapeSample s = static_cast<const Sphere&>(*scene->shapes()[0]).sample_area(rng.next_2d());
        Vec3 d = warp::square_to_uniform_sphere(rng.next_2d());
        SurfaceInteraction si;
        Ray ray = scene->spawn_ray(s.p, s.n, d);
        bool hit = scene->intersect(ray, si);
        if (dot(d, s.n) > 1e-3f) self_hits += hit;  // leaving: must escape
        if (dot(d, s.n) < -1e-3f) misses += !hit;   // entering: must hit the far side
    }
    EXPECT_EQ(self_hits, 0);
    EXPECT_EQ(misses, 0);
}

INSTANTIATE_TEST_SUITE_P(Scales, SpawnScale, ::testing::Values(1e-3f, 1.0f, 1e4f));

}  // namespace
}  // namespace render
