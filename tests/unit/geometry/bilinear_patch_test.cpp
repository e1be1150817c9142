// Bilinear patches (core/shapes/bilinear_patch.h): the bilinear warp against its density
// (chi-square); the area sampling of a mesh of two non-planar patches against the density it
// claims (chi-square over each patch's (u, v), the density found back from the sampled point,
// and the density integrating to one over the surface); hits against a finely tessellated mesh
// of the same patches (distance, normal, hit or miss); orientation; cut-outs.

#include <gtest/gtest.h>

#include <cmath>
#include <memory>

#include "core/base/error.h"
#include "core/lights/area_light.h"
#include "core/sampling/rng.h"
#include "core/scene/scene.h"
#include "core/shapes/alpha_cutout.h"
#include "core/shapes/bilinear_patch.h"
#include "core/shapes/triangle_mesh.h"
#include "tests/support/chi_square.h"

namespace render {
namespace {

testing::ChiSquareFamily family;

// Two patches: a saddle z = (x - 0.5)(y - 0.5)-like twist over [0, 1]^2 and a skewed,
// non-planar quad beside it.
const std::vector<Vec3> kPositions = {Vec3(0, 0, 0),     Vec3(1, 0, 0.6),     Vec3(0, 1, 0.6),
                                      Vec3(1, 1, 0),     Vec3(1.5, 0, 0),     Vec3(3, 0.2, 0.4),
                                      Vec3(1.4, 1.3, 0), Vec3(3.2, 1.7, -0.8)};
const std::vector<uint32_t> kIndices = {0, 1, 2, 3, 4, 5, 6, 7};

std::unique_ptr<BilinearPatches> patches(bool flip = false) {
    return std::make_unique<BilinearPatches>(kPositions, kIndices, std::vector<Vec3>{},
                                             std::vector<Vec2>{}, flip, "test");
}

// The same patches as an n x n grid of quads each (two triangles per quad, vertices on the
// patch), the winding of the patch's dp/du x dp/dv.
std::unique_ptr<TriangleMesh> tessellated(const BilinearPatches& shape, int n) {
    MeshData mesh;
    for (size_t i = 0; i < shape.patch_count(); ++i) {
        const uint32_t base = uint32_t(mesh.positions.size());
        for (int y = 0; y <= n; ++y)
            for (int x = 0; x <= n; ++x)
                mesh.positions.push_back(shape.point(i, double(x) / n, double(y) / n));
        for (int y = 0; y < n; ++y)
            for (int x = 0; x < n; ++x) {
                const uint32_t a = base + uint32_t(y * (n + 1) + x);
                for (uint32_t k : {a, a + 1, a + n + 2, a, a + n + 2, a + n + 1})
                    mesh.indices.push_back(k);
            }
    }
    return std::make_unique<TriangleMesh>(std::move(mesh), Transform(), false, true, "grid");
}

std::unique_ptr<Scene> scene_with(std::unique_ptr<Shape> shape) {
    auto scene = std::make_unique<Scene>();
    scene->set_camera(PerspectiveCamera(Transform(), 45, 'x', 4, 4));
    scene->add_shape(std::move(shape), nullptr);
    scene->commit();
    return scene;
}

CHI_SQUARE_TEST(family, BilinearWarp, MatchesItsDensity, 2) {
    for (const std::array<float, 4>& w :
         {std::array<float, 4>{1, 3, 0.5f, 2}, std::array<float, 4>{0, 1, 2, 0.1f}}) {
        testing::ChiSquareOptions options;
        options.resolution_x = options.resolution_y = 16;
        options.sample_count = 200000;
        const auto r = testing::chi_square_test_2d(
            family,
            [&](Rng& rng) -> std::optional<Vec2> { return sample_bilinear(rng.next_2d(), w); },
            [&](Vec2 p) { return double(bilinear_pdf(p, w)); }, {0, 1, 0, 1}, options);
        EXPECT_TRUE(r.passed) << r.message;
        EXPECT_NEAR(r.pdf_integral, 1.0, 1e-4);
    }
}

// The sampled points, mapped back to (patch + u, v) by locate(), against the claimed density
// times the area element: the density per unit (u, v) of each patch.
CHI_SQUARE_TEST(family, BilinearPatches, AreaSamplingMatchesItsDensity, 1) {
    const auto shape = patches();
    testing::ChiSquareOptions options;
    options.resolution_x = 32;  // 16 per patch
    options.resolution_y = 16;
    options.sample_count = 200000;
    int unlocated = 0;
    const auto r = testing::chi_square_test_2d(
        family,
        [&](Rng& rng) -> std::optional<Vec2> {
            const ShapeSample s = shape->sample_area(rng.next_2d());
            unsigned i;
            Vec2 uv;
            if (!(s.pdf_area > 0) || !shape->locate(s.p, i, uv)) {
                ++unlocated;
                return std::nullopt;
            }
            return Vec2(float(i) + std::min(uv.x, kOneMinusEpsilon), uv.y);
        },
        [&](Vec2 p) {
            const size_t i = std::min<size_t>(size_t(p.x), 1);
            const double u = p.x - double(i), v = p.y;
            return double(shape->pdf_area(unsigned(i), Vec2(float(u), float(v)))) *
                   shape->area_element(i, u, v);
        },
        {0, 2, 0, 1}, options);
    EXPECT_TRUE(r.passed) << r.message;
    EXPECT_NEAR(r.pdf_integral, 1.0, 1e-3);
    EXPECT_EQ(unlocated, 0);
}

// The density a sample reports is the one found back from its point (locate, then pdf_area:
// what AreaLight uses when it has only the point), and it is not uniform (the patches are not
// parallelograms).
TEST(BilinearPatches, SampledDensityIsFoundBackFromThePoint) {
    const auto shape = patches();
    Rng rng(StreamKey{7, 0, 1, 0});
    float lo = kInfinity, hi = 0;
    for (int k = 0; k < 2000; ++k) {
        const ShapeSample s = shape->sample_area(rng.next_2d());
        ASSERT_GT(s.pdf_area, 0);
        unsigned i;
        Vec2 uv;
        ASSERT_TRUE(shape->locate(s.p, i, uv));
        EXPECT_NEAR(shape->pdf_area(i, uv), s.pdf_area, 1e-4f * s.pdf_area);
        lo = std::min(lo, s.pdf_area), hi = std::max(hi, s.pdf_area);
        EXPECT_NEAR(length(s.n), 1.0f, 1e-5f);
    }
    EXPECT_GT(hi / lo, 1.05f);
    unsigned i;
    Vec2 uv;
    EXPECT_FALSE(shape->locate(Vec3(0.5f, 0.5f, 5), i, uv));  // off the surface
    EXPECT_EQ(shape->pdf_area(7, Vec2(0.5f, 0.5f)), 0.0f);    // no such patch
}

// A hit reports the density of the sample it lands on through its own patch and (u, v)
// (SurfaceInteraction::prim_id, prim_uv; no point search), and an area light on the patches
// gives a hit (radiance_at) the densities it gives the hit point alone (radiance). Rays from
// above each sampled point straight down onto it; tolerance 1e-4 relative: the hit's (u, v)
// and the sample's differ by the float rounding of the ray's t.
TEST(BilinearPatches, AHitReportsItsDensityWithoutASearch) {
    auto owned = patches();
    const BilinearPatches* shape = owned.get();
    const auto scene = scene_with(std::move(owned));
    const AreaLight light(shape, Rgb(2.0f));
    Rng rng(StreamKey{8, 0, 1, 0});
    int hits = 0;
    for (int k = 0; k < 2000; ++k) {
        const ShapeSample s = shape->sample_area(rng.next_2d());
        ASSERT_GT(s.pdf_area, 0);
        const Vec3 origin = s.p + s.n * 0.05f;
        SurfaceInteraction si;
        if (!scene->intersect(Ray(origin, -s.n, 0, 1), si)) continue;
        if (length(si.p - s.p) > 1e-4f) continue;  // the other side of a fold
        ++hits;
        EXPECT_EQ(si.shape, shape);
        EXPECT_NEAR(shape->pdf_area(si.prim_id, si.prim_uv), s.pdf_area, 1e-4f * s.pdf_area);
        const LightRadiance at_hit = light.radiance_at(si, -si.geometric_normal);
        const LightRadiance at_point =
            light.radiance(si.p, si.geometric_normal, -si.geometric_normal);
        EXPECT_EQ(at_hit.radiance, Rgb(2.0f));
        EXPECT_NEAR(at_hit.pdf_direct_a, at_point.pdf_direct_a, 1e-4f * at_point.pdf_direct_a);
        EXPECT_NEAR(at_hit.pdf_emission_w, at_point.pdf_emission_w,
                    1e-4f * at_point.pdf_emission_w);
    }
    EXPECT_GT(hits, 1900);
}

// Area against the tessellation (its error is O(1 / n^2) of the curvature).
TEST(BilinearPatches, AreaAndBoundsMatchTheTessellation) {
    const auto shape = patches();
    EXPECT_NEAR(shape->surface_area(), tessellated(*shape, 400)->surface_area(),
                1e-5 * shape->surface_area());
    const Aabb b = shape->bounds();
    EXPECT_EQ(b.lo, Vec3(0, 0, -0.8f));
    EXPECT_EQ(b.hi, Vec3(3.2f, 1.7f, 0.6f));
    EXPECT_THROW(BilinearPatches(kPositions, {0, 1, 2}, {}, {}, false, "bad"), SceneError);
    EXPECT_THROW(BilinearPatches(kPositions, {0, 1, 2, 9}, {}, {}, false, "bad"), SceneError);
}

// Rays from all around at random points of the patches' bounds: the patches and a 512 x 512
// tessellation agree on hit or miss (but for rays within the tessellation error of an edge or
// a silhouette) and on the distance and normal where both hit.
TEST(BilinearPatches, HitsMatchAFineTessellation) {
    const auto exact = scene_with(patches());
    const auto grid = scene_with(tessellated(*patches(), 512));
    Rng rng(StreamKey{11, 0, 1, 0});
    int both = 0, disagree = 0;
    const int rays = 4000;
    for (int k = 0; k < rays; ++k) {
        const Vec3 target(-0.1f + 3.4f * rng.next_1d(), -0.1f + 1.9f * rng.next_1d(),
                          -0.8f + 1.4f * rng.next_1d());
        const float z = 2 * rng.next_1d() - 1, phi = 2 * kPi * rng.next_1d();
        const float r = std::sqrt(std::max(0.0f, 1 - z * z));
        const Vec3 dir(r * std::cos(phi), r * std::sin(phi), z);
        const Ray ray(target - dir * 6.0f, dir);
        SurfaceInteraction a, b;
        const bool hit_a = exact->intersect(ray, a, HitDetail::kWithUv);
        const bool hit_b = grid->intersect(ray, b);
        if (hit_a != hit_b) {
            ++disagree;
            continue;
        }
        if (!hit_a) continue;
        ++both;
        EXPECT_NEAR(a.t, b.t, 2e-3f);
        EXPECT_NEAR(length(a.p - ray.at(a.t)), 0.0f, 1e-4f);
        if (std::abs(a.t - b.t) < 1e-4f) {  // the same sheet
            EXPECT_GT(dot(a.geometric_normal, b.geometric_normal), 0.999f);
        }
    }
    EXPECT_GT(both, rays / 5);
    EXPECT_LE(disagree, 4);
}

TEST(BilinearPatches, FlipNormalsAndVertexNormalsOrientTheSurface) {
    // Seen from above at the saddle's centre, dp/du x dp/dv points up.
    const Ray down(Vec3(0.5f, 0.5f, 5), Vec3(0, 0, -1));
    SurfaceInteraction si;
    ASSERT_TRUE(scene_with(patches(false))->intersect(down, si));
    EXPECT_GT(si.geometric_normal.z, 0.9f);
    EXPECT_NEAR(si.t, 5 - 0.3f, 1e-5f);
    ASSERT_TRUE(scene_with(patches(true))->intersect(down, si));
    EXPECT_LT(si.geometric_normal.z, -0.9f);
    // Downward vertex normals turn the surface over and shade with their interpolation.
    std::vector<Vec3> normals(kPositions.size(), Vec3(0, 0, -1));
    ASSERT_TRUE(scene_with(std::make_unique<BilinearPatches>(kPositions, kIndices, normals,
                                                             std::vector<Vec2>{}, false, "n"))
                    ->intersect(down, si));
    EXPECT_LT(si.geometric_normal.z, -0.9f);
    EXPECT_NEAR(si.shading.n.z, -1.0f, 1e-6f);
}

TEST(BilinearPatches, UvAndTangentsFollowTheTextureCoordinates) {
    // Without uvs: (u, 1 - v); with uvs, their bilinear interpolation, and dp/du, dp/dv the
    // derivatives along them.
    const Ray down(Vec3(0.25f, 0.5f, 5), Vec3(0, 0, -1));
    SurfaceInteraction si;
    ASSERT_TRUE(scene_with(patches())->intersect(down, si, HitDetail::kWithUv));
    EXPECT_NEAR(si.uv.x, 0.25f, 1e-5f);
    EXPECT_NEAR(si.uv.y, 0.5f, 1e-5f);
    std::vector<Vec2> uvs = {Vec2(0, 0), Vec2(2, 0), Vec2(0, 4), Vec2(2, 4),
                             Vec2(0, 0), Vec2(1, 0), Vec2(0, 1), Vec2(1, 1)};
    ASSERT_TRUE(scene_with(std::make_unique<BilinearPatches>(kPositions, kIndices,
                                                             std::vector<Vec3>{}, uvs, false, "uv"))
                    ->intersect(down, si, HitDetail::kWithUv));
    EXPECT_NEAR(si.uv.x, 0.5f, 1e-5f);
    EXPECT_NEAR(si.uv.y, 2.0f, 1e-5f);
    // p(u, v) with u = s / 2, v = t / 4: dp/ds = dp/du / 2.
    EXPECT_NEAR(si.dpdu.x, 0.5f, 1e-5f);
    EXPECT_NEAR(si.dpdv.y, 0.25f, 1e-5f);
}

// A cut-out of alpha 0 removes the patches for every ray.
TEST(BilinearPatches, CutOutDropsHits) {
    auto shape = patches();
    shape->alpha = std::make_shared<AlphaCutout>(FloatParam{0.0f, nullptr});
    SurfaceInteraction si;
    EXPECT_FALSE(
        scene_with(std::move(shape))->intersect(Ray(Vec3(0.5f, 0.5f, 5), Vec3(0, 0, -1)), si));
}

}  // namespace
}  // namespace render
