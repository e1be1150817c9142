// pbrt-v4 alpha cut-outs (core/shapes/alpha_cutout.h) loaded from pbrt scenes:
//   - a quad whose checkerboard alpha texture cuts holes equals, ray by ray (closest hit and
//     occlusion), the same quad with only its opaque squares modelled;
//   - rendered, the two scenes give the same image with path tracing (camera and shadow rays),
//     light tracing and BPT (light paths pass the holes too): block test, k = 5;
//   - analytic shapes: a sphere of alpha 0 is invisible, of alpha 1 opaque; of alpha 0.4 it
//     keeps a fraction 0.4 of the rays that reach it, for closest hits and shadow rays alike;
//   - a bad alpha is refused at its line.

#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "core/base/error.h"
#include "core/render/render_options.h"
#include "core/sampling/rng.h"
#include "core/scene/pbrt/scene_loader.h"
#include "core/scene/scene.h"
#include "tests/support/block_estimate.h"

namespace render {
namespace {

constexpr int kResolution = 32;

std::string header() {
    return R"(LookAt 0 1.2 4  0 0.6 0  0 1 0
Camera "perspective" "float fov" [40]
Film "rgb" "integer xresolution" [32] "integer yresolution" [32]
Integrator "path" "integer maxdepth" [5]
WorldBegin
LightSource "infinite" "rgb L" [0.3 0.3 0.3]
AttributeBegin
  AreaLightSource "diffuse" "rgb L" [10 10 10]
  Shape "trianglemesh" "point3 P" [-0.5 2.5 -0.5  0.5 2.5 -0.5  0.5 2.5 0.5  -0.5 2.5 0.5]
    "integer indices" [0 1 2 0 2 3]
AttributeEnd
AttributeBegin
  Material "diffuse" "rgb reflectance" [0.6 0.6 0.6]
  Shape "trianglemesh" "point3 P" [-3 0 -3  3 0 -3  3 0 3  -3 0 3] "integer indices" [0 1 2 0 2 3]
AttributeEnd
Material "diffuse" "rgb reflectance" [0.8 0.3 0.1]
)";
}

// The quad [-1, 1] x [0.2, 2.2] at z = 0 (uv = its unit square), cut by a 2 x 2 checkerboard:
// uv quadrants (0, 0) and (1, 1) are kept, the other two are holes.
std::string cut_quad() {
    return header() +
           R"(Texture "holes" "float" "checkerboard" "float uscale" [2] "float vscale" [2]
  "float tex1" [1] "float tex2" [0]
Shape "trianglemesh" "point3 P" [-1 0.2 0  1 0.2 0  1 2.2 0  -1 2.2 0]
  "point2 uv" [0 0  1 0  1 1  0 1] "integer indices" [0 1 2 0 2 3] "texture alpha" "holes"
)";
}

// The same two kept squares as quads of their own.
std::string modelled_quad() {
    return header() + R"(Shape "trianglemesh" "point3 P" [-1 0.2 0  0 0.2 0  0 1.2 0  -1 1.2 0]
  "integer indices" [0 1 2 0 2 3]
Shape "trianglemesh" "point3 P" [0 1.2 0  1 1.2 0  1 2.2 0  0 2.2 0]
  "integer indices" [0 1 2 0 2 3]
)";
}

std::unique_ptr<Scene> load(const std::string& text) {
    return pbrt::load_scene_from_string(text, ".");
}

// Rays from random points in front of the quad toward random points on its plane's
// neighbourhood; those that cross the quad's plane within 1e-3 of a square's edge are left out
// (either side of the edge may win there by rounding).
TEST(AlphaCutout, HolesEqualTheModelledGeometryRayByRay) {
    auto cut = load(cut_quad()), modelled = load(modelled_quad());
    Rng rng(StreamKey{5, 0, 0, 0});
    int through_holes = 0, on_squares = 0;
    for (int i = 0; i < 20000; ++i) {
        const Vec3 from(rng.next_1d() * 4 - 2, rng.next_1d() * 2 + 0.2f, 1 + rng.next_1d() * 2);
        const Vec3 to(rng.next_1d() * 3 - 1.5f, rng.next_1d() * 3 - 0.3f, -0.5f - rng.next_1d());
        const Vec3 d = normalize(to - from);
        const float t_plane = -from.z / d.z;
        const Vec3 q = from + d * t_plane;
        const float x = q.x, y = q.y - 1.2f;
        if (std::abs(x) < 1e-3f || std::abs(y) < 1e-3f || std::abs(std::abs(x) - 1) < 1e-3f ||
            std::abs(std::abs(y) - 1) < 1e-3f)
            continue;
        const bool inside = std::abs(x) < 1 && std::abs(y) < 1;
        if (inside) (x < 0) == (y < 0) ? ++on_squares : ++through_holes;
        const Ray ray(from, d);
        SurfaceInteraction a, b;
        const bool hit_a = cut->intersect(ray, a), hit_b = modelled->intersect(ray, b);
        ASSERT_EQ(hit_a, hit_b) << from << " -> " << d;
        if (hit_a) {
            EXPECT_NEAR(a.t, b.t, 1e-4f * (1 + b.t));
        }
        for (const float t_max : {0.5f * t_plane, 2.0f * t_plane, 20.0f}) {
            const Ray shadow(from, d, 0.0f, t_max);
            ASSERT_EQ(cut->occluded(shadow), modelled->occluded(shadow)) << from << " -> " << d;
        }
    }
    EXPECT_GT(through_holes, 500);
    EXPECT_GT(on_squares, 500);
}

testing::BlockEstimate render_blocks(const Scene& scene, const std::string& algorithm) {
    RenderSettings settings = resolve_render_settings(algorithm, {}, scene.settings);
    settings.seed = 99;
    return testing::render_block_estimate(scene, settings, 32, 8, 2);
}

TEST(AlphaCutout, RendersLikeTheModelledGeometry) {
    auto cut = load(cut_quad()), modelled = load(modelled_quad());
    for (const char* algorithm : {"pt", "lt", "bpt"}) {
        SCOPED_TRACE(algorithm);
        const auto a = render_blocks(*cut, algorithm), b = render_blocks(*modelled, algorithm);
        for (const std::string& d : testing::differing_blocks(b, a, 1.0, 5.0))
            ADD_FAILURE() << algorithm << ": " << d;
        for (size_t i = 0; i < a.mean.size(); ++i)
            EXPECT_LT(std::hypot(a.standard_error[i], b.standard_error[i]), 0.1 * b.mean[i])
                << "block " << i / 3 << " channel " << i % 3;
    }
}

// A unit sphere at (0, 1.2, 0), above the floor.
std::string sphere_with_alpha(const std::string& alpha) {
    return header() + "AttributeBegin\nTranslate 0 1.2 0\nShape \"sphere\" \"float radius\" [1] " +
           alpha + "\nAttributeEnd\n";
}

TEST(AlphaCutout, SphereKeepsTheFractionAlphaOfItsHits) {
    auto opaque = load(sphere_with_alpha("\"float alpha\" [1]"));
    auto hole = load(sphere_with_alpha("\"float alpha\" [0]"));
    auto partial = load(sphere_with_alpha("\"float alpha\" [0.4]"));
    Rng rng(StreamKey{6, 0, 0, 0});
    int reached = 0, kept = 0, kept_shadow = 0, passed = 0, kept_back = 0;
    for (int i = 0; i < 20000; ++i) {
        // From random origins on a plane at z = 5 toward the sphere's middle: every ray meets
        // the sphere (front and back) and then the floor or nothing.
        // They pass within 0.5 of the centre at z = 0: front face before t = 5, back after 5.8.
        const Vec3 from(0.5f * rng.next_1d() - 0.25f, 0.5f * rng.next_1d() + 0.95f, 5.0f);
        const Vec3 d =
            normalize(Vec3(rng.next_1d() * 0.1f - 0.05f, rng.next_1d() * 0.1f - 0.05f, -1));
        const Ray ray(from, d), shadow(from, d, 0.0f, 5.5f);  // ends inside the sphere
        SurfaceInteraction s;
        ASSERT_TRUE(opaque->intersect(ray, s));
        const float front = s.t;
        EXPECT_TRUE(opaque->occluded(shadow));
        SurfaceInteraction h;
        if (hole->intersect(ray, h)) {
            EXPECT_GT(h.t, front + 1.0f);  // only the floor behind
        }
        EXPECT_FALSE(hole->occluded(shadow));
        ++reached;
        SurfaceInteraction p;
        // The front face keeps the ray with probability 0.4.
        const bool hit = partial->intersect(ray, p);
        if (hit && std::abs(p.t - front) < 1e-3f) {
            ++kept;
        } else {
            // Past the front face the back face keeps it with probability 0.4 again,
            // independently (its hit distance enters the hash).
            ++passed;
            kept_back += hit && p.t < front + 2.5f;
        }
        kept_shadow += partial->occluded(shadow);
    }
    // Binomial standard error sqrt(0.4 * 0.6 / n): 5 of them.
    const double se = std::sqrt(0.4 * 0.6 / reached);
    EXPECT_NEAR(double(kept) / reached, 0.4, 5 * se);
    EXPECT_NEAR(double(kept_shadow) / reached, 0.4, 5 * se);
    EXPECT_NEAR(double(kept_back) / passed, 0.4, 5 * std::sqrt(0.4 * 0.6 / passed));
}

TEST(AlphaCutout, RefusesBadAlpha) {
    EXPECT_THROW(load(sphere_with_alpha("\"texture alpha\" \"nothere\"")), SceneError);
    EXPECT_THROW(load(sphere_with_alpha("\"float alpha\" [nan]")), SceneError);
    try {
        load(header() +
             "AttributeBegin\nAreaLightSource \"diffuse\" \"rgb L\" [1 1 1]\n"
             "Shape \"sphere\" \"float alpha\" [0.5]\nAttributeEnd\n");
        ADD_FAILURE() << "an emitting cut-out was accepted";
    } catch (const SceneError& e) {
        EXPECT_NE(std::string(e.what()).find("alpha"), std::string::npos) << e.what();
    }
}

}  // namespace
}  // namespace render
