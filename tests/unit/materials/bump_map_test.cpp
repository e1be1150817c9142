// Bump maps (core/materials/bump_map.h) and the dp/dv every shape reports for them.
//
// - dp/dv: at hits on every shape kind, moving along dp/dv by a small step and re-intersecting
//   changes uv by (0, step) to first order (the same finite-difference check normal_map_test
//   makes of dp/du; 2 % tolerance: second-order terms of the curved shapes, float rounding).
// - A constant height texture leaves the frame as it is: the image equals the image without
//   the bump map, bit for bit, with the same seed (pt and bpt).
// - A linear ramp h = a u (times `scale`) on a plane tilts the shading normal by the analytic
//   angle atan(a scale / |dp/du|) against the direction u grows (the displaced plane's own
//   slope); a ramp h = a v on a sphere tilts it by atan(a scale / (pi r)) toward the pole v
//   starts from. Tolerance 1e-4: the finite differences of a linear function are exact up to
//   float rounding at the step 2^-12.
// - bumpmap.xml and bumpmap.pbrt load and render (finite, non-zero images; bumped floors); a
//   pbrt quad and a Mitsuba rectangle with the same height image get the same shading normals.
// - Bad input is refused at its line.

#include <gtest/gtest.h>

#include <cmath>
#include <set>
#include <string>

#include "core/base/error.h"
#include "core/materials/bump_map.h"
#include "core/materials/diffuse.h"
#include "core/math/constants.h"
#include "core/render/render_iterations.h"
#include "core/render/render_options.h"
#include "core/scene/loader/scene_loader.h"
#include "core/scene/pbrt/scene_loader.h"
#include "core/textures/texture.h"
#include "tests/support/every_shape_scene.h"

namespace render {
namespace {

using testing::every_shape_load_error;
using testing::expect_tangent_follows_uv;
using testing::kEveryShapeDir;
using testing::load_every_shape_scene;

const std::string kDiffuse = "<bsdf type=\"diffuse\" id=\"plain\"/>\n";

TEST(BumpMap, EveryShapesDpdvFollowsItsUv) {
    expect_tangent_follows_uv(*load_every_shape_scene(kDiffuse, "<ref id=\"plain\"/>"), 1);
}

TEST(BumpMap, AConstantHeightRendersAsNoBumpMap) {
    auto plain = load_every_shape_scene(kDiffuse, "<ref id=\"plain\"/>");
    auto bumped = load_every_shape_scene(
        "<bsdf type=\"bumpmap\" id=\"bumped\"><texture type=\"checkerboard\" name=\"h\">"
        "<rgb name=\"color0\" value=\"0.3\"/><rgb name=\"color1\" value=\"0.3\"/></texture>"
        "<float name=\"scale\" value=\"5\"/><bsdf type=\"diffuse\"/></bsdf>\n",
        "<ref id=\"bumped\"/>");
    for (const std::string algorithm : {"pt", "bpt"}) {
        RenderSettings settings = resolve_render_settings(algorithm, {}, plain->settings);
        settings.seed = 5;
        const IterationResult a = render_iterations(*plain, settings, 0, IterationRange{1, 5});
        const IterationResult b = render_iterations(*bumped, settings, 0, IterationRange{1, 5});
        ASSERT_EQ(a.sum.values().size(), b.sum.values().size());
        double total = 0;
        for (size_t i = 0; i < a.sum.values().size(); ++i) {
            ASSERT_EQ(a.sum.values()[i], b.sum.values()[i]) << algorithm << " value " << i;
            total += a.sum.values()[i];
        }
        EXPECT_GT(total, 0.0);
    }
}

// h = a u + b v, grey.
class RampTexture final : public Texture {
  public:
    RampTexture(float a, float b) : a_(a), b_(b) {}
    Rgb eval(Vec2 uv) const override { return Rgb(a_ * uv.x + b_ * uv.y); }
    Rgb mean() const override { return Rgb(0.5f * (a_ + b_)); }
    float min_value() const override { return std::min({0.0f, a_, b_, a_ + b_}); }
    float max_value() const override { return std::max({0.0f, a_, b_, a_ + b_}); }
    std::string to_string() const override { return "ramp"; }

  private:
    float a_, b_;
};

void expect_tilt(const Frame& f, const Vec3& n, const Vec3& away, float angle) {
    // The new normal is n turned by `angle` away from unit `away` (orthogonal to n).
    const Vec3 want = n * std::cos(angle) - away * std::sin(angle);
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(f.n[c], want[c], 1e-4f) << c;
    EXPECT_NEAR(dot(f.s, f.n), 0.0f, 1e-5f);
    EXPECT_NEAR(length(f.s), 1.0f, 1e-5f);
    EXPECT_NEAR(dot(cross(f.s, f.t), f.n), 1.0f, 1e-5f);
}

TEST(BumpMap, ALinearRampTiltsByTheAnalyticAngle) {
    auto plain = load_every_shape_scene(kDiffuse, "<ref id=\"plain\"/>");
    auto diffuse = std::make_shared<DiffuseBsdf>(Rgb(0.5f));
    // The floor: a rectangle 6 wide along its object x axis (u), turned 20 degrees about y:
    // dp/du = 6 (cos 20, 0, -sin 20). h = 0.7 u, scale 2: the displaced plane rises 1.4 per unit
    // of u, 1.4 / 6 per unit length.
    SurfaceInteraction si;
    ASSERT_TRUE(
        plain->intersect(Ray(Vec3(-0.3f, 2, 0.5f), Vec3(0, -1, 0)), si, HitDetail::kWithUv));
    const float a20 = 20 * kPi / 180;
    const Vec3 along_u(std::cos(a20), 0, -std::sin(a20));
    for (const float a : {0.7f, -0.3f, 3.0f}) {
        const BumpMapBsdf bump(diffuse, std::make_shared<RampTexture>(a, 0.0f), 2.0f);
        expect_tilt(bump.shading_frame(si), Vec3(0, 1, 0), along_u, std::atan(a * 2 / 6));
    }
    // The sphere (radius 0.6, centre (-1.2, 0.6, 0) before a -70 degree turn about x): v =
    // theta / pi from its object z axis R(z), so |dp/dv| = pi r and v grows away from R(z).
    const float b = -70 * kPi / 180;
    const Vec3 centre(-1.2f, 0.6f * std::cos(b), 0.6f * std::sin(b));
    const Vec3 axis(0, -std::sin(b), std::cos(b));
    ASSERT_TRUE(plain->intersect(Ray(centre + Vec3(0.2f, 2, 0.3f), Vec3(0, -1, 0)), si,
                                 HitDetail::kWithUv));
    const Vec3 n = normalize(si.p - centre);
    const Vec3 along_v = normalize(n * dot(n, axis) - axis);  // away from the pole R(z)
    const BumpMapBsdf bump(diffuse, std::make_shared<RampTexture>(0.0f, 0.5f), 1.5f);
    expect_tilt(bump.shading_frame(si), n, along_v, std::atan(0.5f * 1.5f / (kPi * 0.6f)));
    // A ramp along u there: |dp/du| = 2 pi r sin(theta), tilted against the phi direction.
    const Vec3 along_phi = normalize(cross(axis, n));
    const float sin_theta = length(cross(axis, n));
    const BumpMapBsdf bump_u(diffuse, std::make_shared<RampTexture>(0.25f, 0.0f), 1.0f);
    expect_tilt(bump_u.shading_frame(si), n, along_phi,
                std::atan(0.25f / (2 * kPi * 0.6f * sin_theta)));
}

struct Rendered {
    double total = 0;
    bool finite = true;
};

Rendered render_a_little(const Scene& scene, const std::string& algorithm) {
    RenderSettings settings = resolve_render_settings(algorithm, {}, scene.settings);
    settings.seed = 3;
    const IterationResult r = render_iterations(scene, settings, 0, IterationRange{1, 2});
    Rendered out;
    for (float v : r.sum.values()) {
        out.finite = out.finite && std::isfinite(v);
        out.total += v;
    }
    return out;
}

// The share of floor hits whose shading normal is tilted.
double tilted_floor_share(const Scene& scene) {
    int hits = 0, tilted = 0;
    for (int i = 0; i < 200; ++i) {
        SurfaceInteraction si;
        const Ray down(Vec3(-2.5f + 0.025f * i, 2.9f, 2.4f - 0.011f * i), Vec3(0, -1, 0));
        if (!scene.intersect(down, si) || std::abs(si.p.y) > 1e-3f) continue;
        ++hits;
        tilted += si.shading.n.y < 0.9999f;
    }
    return hits > 0 ? double(tilted) / hits : 0;
}

TEST(BumpMap, ShippedScenesLoadAndRenderInBothFormats) {
    auto mitsuba = load_scene(kEveryShapeDir + "/bumpmap.xml");
    auto pbrt = pbrt::load_scene(kEveryShapeDir + "/bumpmap.pbrt");
    for (const Scene* scene : {mitsuba.get(), pbrt.get()}) {
        for (const std::string algorithm : {"pt", "vcm"}) {
            const Rendered r = render_a_little(*scene, algorithm);
            EXPECT_TRUE(r.finite) << algorithm;
            EXPECT_GT(r.total, 0.0) << algorithm;
        }
        EXPECT_GT(tilted_floor_share(*scene), 0.5);
    }
}

// pbrt-v4's "texture displacement" is Mitsuba's bumpmap with scale 1 around the material: a
// pbrt quad and a Mitsuba rectangle with the same uv and height image get the same normals.
TEST(BumpMap, PbrtDisplacementMatchesMitsubasBumpMap) {
    auto mitsuba = load_scene_from_string(
        "<scene version=\"3.0.0\"><sensor type=\"perspective\"/>"
        "<shape type=\"rectangle\"><bsdf type=\"bumpmap\">"
        "<texture type=\"bitmap\" name=\"h\"><string name=\"filename\" "
        "value=\"textures/tiles.png\"/><boolean name=\"raw\" value=\"true\"/></texture>"
        "<bsdf type=\"twosided\"><bsdf type=\"diffuse\"/></bsdf></bsdf></shape></scene>",
        kEveryShapeDir);
    auto pbrt = pbrt::load_scene_from_string(
        "Camera \"perspective\"\nWorldBegin\n"
        "Texture \"h\" \"float\" \"imagemap\" \"string filename\" \"textures/tiles.png\"\n"
        "  \"string encoding\" \"linear\"\n"
        "Material \"diffuse\" \"texture displacement\" \"h\"\n"
        "Shape \"trianglemesh\" \"point3 P\" [-1 -1 0 1 -1 0 1 1 0 -1 1 0]\n"
        "  \"integer indices\" [0 1 2 0 2 3] \"point2 uv\" [0 1 1 1 1 0 0 0]\n",
        kEveryShapeDir);
    int tilted = 0;
    for (int i = 0; i < 100; ++i) {
        const Ray down(Vec3(-0.95f + 0.019f * i, 0.37f - 0.013f * i, 2), Vec3(0, 0, -1));
        SurfaceInteraction a, b;
        ASSERT_TRUE(mitsuba->intersect(down, a));
        ASSERT_TRUE(pbrt->intersect(down, b));
        for (int c = 0; c < 3; ++c) EXPECT_NEAR(a.shading.n[c], b.shading.n[c], 1e-4f) << i;
        tilted += a.shading.n.z < 0.999f;
    }
    EXPECT_GT(tilted, 50);
}

std::string pbrt_error(const std::string& world) {
    try {
        pbrt::load_scene_from_string("Camera \"perspective\"\nWorldBegin\n" + world,
                                     kEveryShapeDir);
    } catch (const SceneError& e) {
        return e.what();
    }
    return "loaded";
}

const std::string kHeight =
    "<texture type=\"checkerboard\" name=\"h\"><rgb name=\"color0\" value=\"0.3\"/></texture>";

TEST(BumpMap, RefusalsNameTheLine) {
    // kEveryShapeHead is 4 lines; the body starts on line 5.
    const std::string nested = every_shape_load_error(
        "<bsdf type=\"twosided\" id=\"t\">\n  <bsdf "
        "type=\"bumpmap\">" +
        kHeight + "<bsdf type=\"diffuse\"/></bsdf>\n</bsdf>\n");
    EXPECT_NE(nested.find("<string>:5"), std::string::npos) << nested;
    EXPECT_NE(nested.find("cannot wrap a normalmap or bumpmap"), std::string::npos) << nested;
    const std::string no_height =
        every_shape_load_error("\n<bsdf type=\"bumpmap\"><bsdf type=\"diffuse\"/></bsdf>\n");
    EXPECT_NE(no_height.find("<string>:6"), std::string::npos) << no_height;
    EXPECT_NE(no_height.find("needs a height <texture>"), std::string::npos) << no_height;
    const std::string no_bsdf =
        every_shape_load_error("<bsdf type=\"bumpmap\">" + kHeight + "</bsdf>\n");
    EXPECT_NE(no_bsdf.find("needs one nested bsdf"), std::string::npos) << no_bsdf;
    const std::string two = every_shape_load_error("<bsdf type=\"bumpmap\">" + kHeight +
                                                   "\n<texture type=\"checkerboard\" name=\"k\"/>"
                                                   "<bsdf type=\"diffuse\"/></bsdf>\n");
    EXPECT_NE(two.find("<string>:6"), std::string::npos) << two;
    EXPECT_NE(two.find("takes one texture"), std::string::npos) << two;
    const std::string bad_scale = every_shape_load_error("<bsdf type=\"bumpmap\">" + kHeight +
                                                         "\n<float name=\"scale\" value=\"nan\"/>"
                                                         "<bsdf type=\"diffuse\"/></bsdf>\n");
    EXPECT_NE(bad_scale.find("<string>:6"), std::string::npos) << bad_scale;
    const std::string in_bump =
        every_shape_load_error("<bsdf type=\"bumpmap\">" + kHeight + "<bsdf type=\"bumpmap\">\n" +
                               kHeight + "<bsdf type=\"diffuse\"/></bsdf></bsdf>\n");
    EXPECT_NE(in_bump.find("cannot wrap another bumpmap"), std::string::npos) << in_bump;
    EXPECT_EQ(
        every_shape_load_error("<bsdf type=\"bumpmap\">" + kHeight +
                               "<bsdf type=\"twosided\"><bsdf type=\"diffuse\"/></bsdf></bsdf>\n"),
        "loaded");

    // pbrt: the material's line (3: after Camera and WorldBegin).
    const std::string unknown = pbrt_error("Material \"diffuse\" \"texture displacement\" \"x\"\n");
    EXPECT_NE(unknown.find(":3"), std::string::npos) << unknown;
    EXPECT_NE(unknown.find("unknown float texture \"x\""), std::string::npos) << unknown;
    const std::string plain = pbrt_error("Material \"diffuse\" \"float displacement\" [1]\n");
    EXPECT_NE(plain.find(":3"), std::string::npos) << plain;
    EXPECT_NE(plain.find("expects \"texture displacement\""), std::string::npos) << plain;
    const std::string both = pbrt_error(
        "Texture \"h\" \"float\" \"constant\" \"float value\" [1]\n"
        "Material \"diffuse\" \"texture displacement\" \"h\" \"string normalmap\" "
        "\"textures/tiles.png\"\n");
    EXPECT_NE(both.find(":4"), std::string::npos) << both;
    EXPECT_NE(both.find("a normalmap and a displacement together"), std::string::npos) << both;
    const std::string mixed = pbrt_error(
        "Texture \"h\" \"float\" \"constant\" \"float value\" [1]\n"
        "MakeNamedMaterial \"b\" \"string type\" \"diffuse\" \"texture displacement\" "
        "\"h\"\n"
        "MakeNamedMaterial \"d\" \"string type\" \"diffuse\"\n"
        "Material \"mix\" \"string materials\" [\"b\" \"d\"]\n");
    EXPECT_NE(mixed.find(":6"), std::string::npos) << mixed;
    EXPECT_NE(mixed.find("a material with a normal or bump map"), std::string::npos) << mixed;
}

}  // namespace
}  // namespace render
