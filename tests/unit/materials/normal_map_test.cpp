// Normal maps (core/materials/normal_map.h) and the dp/du every shape reports for them.
//
// - dp/du: at hits on every shape kind (rectangle, cube, sphere, disk, a mesh with uv, a mesh
//   without, an instance with a non-uniform scale), moving along dp/du by a small step and
//   re-intersecting changes uv by (step, 0) to first order: a finite-difference check of the
//   tangent against each shape's own uv map (2 % tolerance: second-order terms of the curved
//   shapes and float rounding at a step of 1e-3 of the scene).
// - A flat normal map (0.5, 0.5, 1) leaves the frame as it is: the image equals the image
//   without the map, bit for bit, with the same seed.
// - A tilted map (0.75, 0.5, 0.8) turns the shading normal to normalize(0.5 s + 0.6 n) with s
//   the unit tangent along dp/du, computed here from each shape's geometry (the rectangle's
//   x axis, the sphere's phi direction), for the plain shapes and an instance.
// - A normalmap nested in a wrapper, a missing map or nested bsdf are errors at their line.

#include <gtest/gtest.h>

#include <cmath>
#include <set>
#include <string>

#include "core/base/error.h"
#include "core/render/render_iterations.h"
#include "core/render/render_options.h"
#include "core/scene/loader/scene_loader.h"
#include "core/scene/pbrt/scene_loader.h"
#include "tests/support/every_shape_scene.h"

namespace render {
namespace {

using testing::every_shape_load_error;
using testing::expect_tangent_follows_uv;
using testing::load_every_shape_scene;

const std::string kDiffuse = "<bsdf type=\"diffuse\" id=\"plain\"/>\n";
std::string normal_mapped(const std::string& rgb) {
    return "<bsdf type=\"normalmap\" id=\"mapped\"><rgb name=\"normalmap\" value=\"" + rgb +
           "\"/><bsdf type=\"diffuse\"/></bsdf>\n";
}

TEST(NormalMap, EveryShapesTangentFollowsItsUv) {
    expect_tangent_follows_uv(*load_every_shape_scene(kDiffuse, "<ref id=\"plain\"/>"), 0);
}

TEST(NormalMap, AFlatMapRendersAsNoMap) {
    auto plain = load_every_shape_scene(kDiffuse, "<ref id=\"plain\"/>");
    auto mapped = load_every_shape_scene(normal_mapped("0.5, 0.5, 1"), "<ref id=\"mapped\"/>");
    for (const std::string algorithm : {"pt", "bpt"}) {
        RenderSettings settings = resolve_render_settings(algorithm, {}, plain->settings);
        settings.seed = 5;
        const IterationResult a = render_iterations(*plain, settings, 0, IterationRange{1, 5});
        const IterationResult b = render_iterations(*mapped, settings, 0, IterationRange{1, 5});
        ASSERT_EQ(a.sum.values().size(), b.sum.values().size());
        double total = 0;
        for (size_t i = 0; i < a.sum.values().size(); ++i) {
            ASSERT_EQ(a.sum.values()[i], b.sum.values()[i]) << algorithm << " value " << i;
            total += a.sum.values()[i];
        }
        EXPECT_GT(total, 0.0);
    }
}

TEST(NormalMap, ATiltedMapTurnsTheShadingNormalAlongTheTangent) {
    auto scene = load_every_shape_scene(normal_mapped("0.75, 0.5, 0.8"), "<ref id=\"mapped\"/>");
    auto plain = load_every_shape_scene(kDiffuse, "<ref id=\"plain\"/>");
    // The local normal (0.5, 0, 0.6): n' = normalize(0.5 s + 0.6 n).
    auto expect_tilt = [](const SurfaceInteraction& si, const Vec3& n, const Vec3& s) {
        const Vec3 want = normalize(s * 0.5f + n * 0.6f);
        for (int c = 0; c < 3; ++c) EXPECT_NEAR(si.shading.n[c], want[c], 1e-4f) << c;
        EXPECT_NEAR(dot(si.shading.s, si.shading.n), 0.0f, 1e-5f);
        EXPECT_NEAR(length(si.shading.s), 1.0f, 1e-5f);
    };
    // The floor: a rectangle whose u runs along its object x axis, scaled by 3, turned 20
    // degrees about y: s = (cos 20, 0, -sin 20).
    SurfaceInteraction si, bare;
    const Ray down(Vec3(-0.3f, 2, 0.5f), Vec3(0, -1, 0));
    ASSERT_TRUE(scene->intersect(down, si));
    ASSERT_TRUE(plain->intersect(down, bare));
    const float a = 20 * kPi / 180;
    expect_tilt(si, Vec3(0, 1, 0), Vec3(std::cos(a), 0, -std::sin(a)));
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(bare.shading.n[c], c == 1 ? 1.0f : 0.0f, 1e-6f);
    // The sphere (centre (-1.2, 0.6, 0) before a -70 degree turn about x): u turns about its
    // object z axis, now R(z); s = normalize(R(z) x (p - c)).
    const float b = -70 * kPi / 180;
    const Vec3 centre(-1.2f, 0.6f * std::cos(b), 0.6f * std::sin(b));
    const Vec3 axis(0, -std::sin(b), std::cos(b));
    const Ray toward(centre + Vec3(0.2f, 2, 0.3f), Vec3(0, -1, 0));
    ASSERT_TRUE(scene->intersect(toward, si));
    ASSERT_TRUE(plain->intersect(toward, bare));
    const Vec3 outward = normalize(si.p - centre);
    expect_tilt(si, outward, normalize(cross(axis, outward)));
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(bare.shading.n[c], outward[c], 1e-4f);
    // The instanced sphere (radius 0.3 at the origin, scaled (1.5, 0.8, 1), moved to
    // (1.4, 0.3, 1.2)): its normal is the ellipsoid's, its tangent the scaled phi direction.
    const Ray onto(Vec3(1.5f, 3, 1.25f), Vec3(0, -1, 0));
    ASSERT_TRUE(scene->intersect(onto, si));
    const Vec3 local = Vec3((si.p.x - 1.4f) / 1.5f, (si.p.y - 0.3f) / 0.8f, si.p.z - 1.2f);
    const Vec3 n = normalize(Vec3(local.x / 1.5f, local.y / 0.8f, local.z));
    const Vec3 phi = cross(Vec3(0, 0, 1), local);
    const Vec3 t = Vec3(phi.x * 1.5f, phi.y * 0.8f, phi.z);
    expect_tilt(si, n, normalize(t - n * dot(n, t)));
}

// pbrt-v4's "string normalmap" is Mitsuba's normalmap around the material with a raw bitmap:
// a pbrt quad and a Mitsuba rectangle with the same uv get the same shading normals.
TEST(NormalMap, PbrtNormalMapsMatchMitsubas) {
    const std::string dir = std::string(RENDER_SOURCE_DIR) + "/scenes/tests";
    auto mitsuba = load_scene_from_string(
        "<scene version=\"3.0.0\"><sensor type=\"perspective\"/>"
        "<shape type=\"rectangle\"><bsdf type=\"normalmap\">"
        "<texture type=\"bitmap\" name=\"normalmap\"><string name=\"filename\" "
        "value=\"textures/tiles.png\"/><boolean name=\"raw\" value=\"true\"/></texture>"
        "<bsdf type=\"twosided\"><bsdf type=\"diffuse\"/></bsdf></bsdf></shape></scene>",
        dir);
    auto pbrt = pbrt::load_scene_from_string(
        "Camera \"perspective\"\nWorldBegin\n"
        "Material \"diffuse\" \"string normalmap\" \"textures/tiles.png\"\n"
        "Shape \"trianglemesh\" \"point3 P\" [-1 -1 0 1 -1 0 1 1 0 -1 1 0]\n"
        "  \"integer indices\" [0 1 2 0 2 3] \"point2 uv\" [0 1 1 1 1 0 0 0]\n",
        dir);
    int tilted = 0;
    for (int i = 0; i < 100; ++i) {
        const Ray down(Vec3(-0.95f + 0.019f * i, 0.37f - 0.013f * i, 2), Vec3(0, 0, -1));
        SurfaceInteraction a, b;
        ASSERT_TRUE(mitsuba->intersect(down, a));
        ASSERT_TRUE(pbrt->intersect(down, b));
        for (int c = 0; c < 3; ++c) EXPECT_NEAR(a.shading.n[c], b.shading.n[c], 1e-5f) << i;
        tilted += a.shading.n.z < 0.999f;
    }
    EXPECT_GT(tilted, 50);  // tiles.png is no flat map
}

TEST(NormalMap, RefusalsNameTheLine) {
    // kEveryShapeHead is 4 lines; the body starts on line 5.
    const std::string nested = every_shape_load_error(
        "<bsdf type=\"twosided\" id=\"t\">\n"
        "  <bsdf type=\"normalmap\"><rgb name=\"normalmap\" value=\"0.5, 0.5, 1\"/>"
        "<bsdf type=\"diffuse\"/></bsdf>\n"
        "</bsdf>\n");
    EXPECT_NE(nested.find("<string>:5"), std::string::npos) << nested;
    EXPECT_NE(nested.find("cannot wrap a normalmap"), std::string::npos) << nested;
    const std::string no_map =
        every_shape_load_error("<bsdf type=\"normalmap\"><bsdf type=\"diffuse\"/></bsdf>\n");
    EXPECT_NE(no_map.find("needs a \"normalmap\" texture"), std::string::npos) << no_map;
    const std::string no_bsdf = every_shape_load_error(
        "<bsdf type=\"normalmap\"><rgb name=\"normalmap\" value=\"0.5\"/></bsdf>\n");
    EXPECT_NE(no_bsdf.find("needs one nested bsdf"), std::string::npos) << no_bsdf;
    EXPECT_EQ(every_shape_load_error(
                  "<bsdf type=\"normalmap\"><rgb name=\"normalmap\" value=\"0.5, 0.5, 1\"/>"
                  "<bsdf type=\"twosided\"><bsdf type=\"diffuse\"/></bsdf></bsdf>\n"),
              "loaded");
}

}  // namespace
}  // namespace render
