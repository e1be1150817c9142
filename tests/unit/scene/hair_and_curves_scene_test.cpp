// The loaders' side of pbrt-v4's `hair` material and `curve` shape and of Mitsuba 3's
// `bsplinecurve`/`linearcurve`: what each parameter becomes, what is refused, and the shipped
// scenes of these features (scenes/tests/hair.pbrt, curves.pbrt, curves.xml).

#include <gtest/gtest.h>

#include <string>

#include "core/base/error.h"
#include "core/materials/hair.h"
#include "core/scene/loader/scene_loader.h"
#include "core/scene/pbrt/scene_loader.h"
#include "core/scene/scene.h"
#include "core/shapes/curve.h"

namespace render {
namespace {

std::unique_ptr<Scene> pbrt_scene(const std::string& world) {
    return pbrt::load_scene_from_string("WorldBegin\n" + world, ".");
}

const Curves* curves_of(const Scene& scene, size_t i) {
    return dynamic_cast<const Curves*>(scene.shapes().at(i).get());
}

TEST(HairAndCurvesScene, PbrtCurveKindsBasesAndDegrees) {
    auto scene = pbrt_scene(
        "Shape \"curve\" \"point3 P\" [0 0 0 1 0 0 2 1 0 3 0 0] \"float width\" [0.1]\n"
        "Shape \"curve\" \"string type\" \"cylinder\" \"string basis\" \"bspline\" "
        "\"point3 P\" [0 0 0 1 0 0 2 1 0 3 0 0 4 1 0]\n"
        "Shape \"curve\" \"string type\" \"ribbon\" \"integer degree\" [2] "
        "\"point3 P\" [0 0 0 1 0 0 2 1 0 3 0 0 4 1 0] \"normal N\" [0 0 1 0 1 0 0 0 1]\n");
    ASSERT_EQ(scene->shapes().size(), 3u);
    ASSERT_TRUE(curves_of(*scene, 0) && curves_of(*scene, 1) && curves_of(*scene, 2));
    EXPECT_EQ(curves_of(*scene, 0)->type(), CurveType::Flat);  // pbrt-v4's default
    EXPECT_EQ(curves_of(*scene, 0)->segment_count(), 1u);
    EXPECT_FLOAT_EQ(curves_of(*scene, 0)->segment(0).radius[0], 0.05f);
    EXPECT_EQ(curves_of(*scene, 1)->type(), CurveType::Cylinder);
    EXPECT_EQ(curves_of(*scene, 1)->segment_count(), 2u);               // 5 points, cubic B-spline
    EXPECT_FLOAT_EQ(curves_of(*scene, 1)->segment(0).radius[0], 0.5f);  // width 1 by default
    EXPECT_EQ(curves_of(*scene, 2)->type(), CurveType::Ribbon);
    EXPECT_EQ(curves_of(*scene, 2)->segment_count(), 2u);
}

TEST(HairAndCurvesScene, PbrtCurveRefusals) {
    const char* bad[] = {
        // ribbon without normals; wrong normal count; degree 4; unknown type and basis; a
        // Bezier point count that is not 3n + 1; an area light on a curve
        "Shape \"curve\" \"string type\" \"ribbon\" \"point3 P\" [0 0 0 1 0 0 2 1 0 3 0 0]",
        "Shape \"curve\" \"string type\" \"ribbon\" \"point3 P\" [0 0 0 1 0 0 2 1 0 3 0 0] "
        "\"normal N\" [0 0 1]",
        "Shape \"curve\" \"integer degree\" [4] \"point3 P\" [0 0 0 1 0 0 2 1 0 3 0 0 4 0 0]",
        "Shape \"curve\" \"string type\" \"tube\" \"point3 P\" [0 0 0 1 0 0 2 1 0 3 0 0]",
        "Shape \"curve\" \"string basis\" \"hermite\" \"point3 P\" [0 0 0 1 0 0 2 1 0 3 0 0]",
        "Shape \"curve\" \"point3 P\" [0 0 0 1 0 0 2 1 0 3 0 0 4 0 0]",
        "AreaLightSource \"diffuse\" Shape \"curve\" \"point3 P\" [0 0 0 1 0 0 2 1 0 3 0 0]",
        "Shape \"curve\" \"float width\" [-1] \"point3 P\" [0 0 0 1 0 0 2 1 0 3 0 0]",
    };
    for (const char* world : bad) EXPECT_THROW(pbrt_scene(world), SceneError) << world;
    // splitdepth means nothing here: read (with a warning), not refused.
    EXPECT_NO_THROW(pbrt_scene(
        "Shape \"curve\" \"integer splitdepth\" [5] \"point3 P\" [0 0 0 1 0 0 2 1 0 3 0 0]"));
}

TEST(HairAndCurvesScene, PbrtHairMaterial) {
    auto scene = pbrt_scene(
        "Material \"hair\" \"rgb sigma_a\" [0.5 0.6 0.7] \"float beta_m\" [0.2] \"float alpha\" "
        "[3]\n"
        "Shape \"curve\" \"point3 P\" [0 0 0 1 0 0 2 1 0 3 0 0]\n"
        "Material \"hair\"\n"
        "Shape \"curve\" \"point3 P\" [0 0 0 1 0 0 2 1 0 3 0 0]\n");
    ASSERT_EQ(scene->shapes().size(), 2u);
    const Bsdf* first = scene->shapes()[0]->bsdf;
    ASSERT_TRUE(first->varies());  // h comes from each hit's v
    const auto at = std::dynamic_pointer_cast<const HairBsdf>(first->at(Vec2(0.5f, 0.25f)));
    ASSERT_TRUE(at);
    EXPECT_FLOAT_EQ(at->h(), -0.5f);
    HairParams expected;
    expected.sigma_a = Rgb(0.5f, 0.6f, 0.7f);
    expected.beta_m = 0.2f;
    expected.alpha = 3;
    EXPECT_EQ(at->to_string(), HairBsdf(expected, -0.5f).to_string());
    HairParams defaults;
    defaults.sigma_a = HairBsdf::sigma_a_from_concentration(1.3f, 0);
    EXPECT_EQ(scene->shapes()[1]->bsdf->at(Vec2(0, 0.5f))->to_string(),
              HairBsdf(defaults, 0).to_string());
    // A texture outside its parameter's range is refused as a constant would be.
    EXPECT_THROW(pbrt_scene("Texture \"t\" \"float\" \"checkerboard\" \"float tex1\" [0.5] "
                            "\"float tex2\" [2]\n"
                            "Material \"hair\" \"texture beta_m\" \"t\"\n"
                            "Shape \"curve\" \"point3 P\" [0 0 0 1 0 0 2 1 0 3 0 0]"),
                 SceneError);
    EXPECT_THROW(pbrt_scene("Material \"hair\" \"rgb sigma_a\" [1 1 1] \"rgb reflectance\" [0.5 "
                            "0.5 0.5]\nShape \"curve\" \"point3 P\" [0 0 0 1 0 0 2 1 0 3 0 0]"),
                 SceneError);
}

// Textured hair parameters (pbrt-v4's): looked up at the hit's uv, each texel giving the
// parameters a constant of its value would. A checkerboard of eumelanin 0.5 and 2 (2 x 2 cells
// over uv) and one of beta_n 0.2 and 0.6 under a textured reflectance's constant.
TEST(HairAndCurvesScene, PbrtHairTexturedParameters) {
    auto scene = pbrt_scene(
        "Texture \"mel\" \"float\" \"checkerboard\" \"float tex1\" [0.5] \"float tex2\" [2] "
        "\"float uscale\" [2] \"float vscale\" [2]\n"
        "Texture \"bn\" \"float\" \"checkerboard\" \"float tex1\" [0.2] \"float tex2\" [0.6] "
        "\"float uscale\" [2] \"float vscale\" [2]\n"
        "Material \"hair\" \"texture eumelanin\" \"mel\" \"float pheomelanin\" [0.3]\n"
        "Shape \"curve\" \"point3 P\" [0 0 0 1 0 0 2 1 0 3 0 0]\n"
        "Material \"hair\" \"rgb reflectance\" [0.4 0.3 0.2] \"texture beta_n\" \"bn\"\n"
        "Shape \"curve\" \"point3 P\" [0 0 0 1 0 0 2 1 0 3 0 0]\n");
    ASSERT_EQ(scene->shapes().size(), 2u);
    // Two uvs in neighbouring cells of the checkerboards (u differs by a cell).
    const Vec2 a(0.1f, 0.9f), b(0.6f, 0.9f);
    const auto hair_at = [&](size_t shape, Vec2 uv) {
        return scene->shapes()[shape]->bsdf->at(uv)->to_string();
    };
    const auto melanin = [&](float eu, Vec2 uv) {
        HairParams p;
        p.sigma_a = HairBsdf::sigma_a_from_concentration(eu, 0.3f);
        return HairBsdf(p, -1 + 2 * uv.y).to_string();
    };
    const bool a_first = hair_at(0, a) == melanin(0.5f, a);
    EXPECT_EQ(hair_at(0, a), a_first ? melanin(0.5f, a) : melanin(2, a));
    EXPECT_EQ(hair_at(0, b), a_first ? melanin(2, b) : melanin(0.5f, b));
    const auto reflectance = [&](float beta_n, Vec2 uv) {
        HairParams p;
        p.beta_n = beta_n;
        p.sigma_a = HairBsdf::sigma_a_from_reflectance(Rgb(0.4f, 0.3f, 0.2f), beta_n);
        return HairBsdf(p, -1 + 2 * uv.y).to_string();
    };
    EXPECT_EQ(hair_at(1, a), a_first ? reflectance(0.2f, a) : reflectance(0.6f, a));
    EXPECT_EQ(hair_at(1, b), a_first ? reflectance(0.6f, b) : reflectance(0.2f, b));
    EXPECT_NE(hair_at(1, a), hair_at(1, b));
}

// Curves are not area lights in either format (they have no area sampling).
TEST(HairAndCurvesScene, MitsubaCurveEmitterIsRefused) {
    const std::string dir = std::string(RENDER_SOURCE_DIR) + "/scenes/tests";
    EXPECT_THROW(load_scene_from_string(R"(<scene version="3.0.0">
  <shape type="linearcurve">
    <string name="filename" value="curves-linear.txt"/>
    <emitter type="area"><rgb name="radiance" value="1"/></emitter>
  </shape>
</scene>)",
                                        dir),
                 SceneError);
}

TEST(HairAndCurvesScene, ShippedScenesLoad) {
    const std::string dir = std::string(RENDER_SOURCE_DIR) + "/scenes/tests/";
    auto hair = pbrt::load_scene(dir + "hair.pbrt");
    int fibres = 0;
    for (const auto& s : hair->shapes())
        if (const auto* c = dynamic_cast<const Curves*>(s.get())) {
            ++fibres;
            EXPECT_EQ(c->type(), CurveType::Cylinder);
            EXPECT_TRUE(std::dynamic_pointer_cast<const HairBsdf>(s->bsdf->at(Vec2(0.5f, 0.5f))));
        }
    EXPECT_EQ(fibres, 300);
    auto curves = pbrt::load_scene(dir + "curves.pbrt");
    int kinds[3] = {0, 0, 0}, cut = 0;
    for (const auto& s : curves->shapes())
        if (const auto* c = dynamic_cast<const Curves*>(s.get())) {
            ++kinds[int(c->type())];
            cut += s->alpha != nullptr;
        }
    EXPECT_EQ(kinds[int(CurveType::Flat)], 2);
    EXPECT_EQ(kinds[int(CurveType::Cylinder)], 2);
    EXPECT_EQ(kinds[int(CurveType::Ribbon)], 1);
    EXPECT_EQ(cut, 1);
    auto mitsuba = load_scene(dir + "curves.xml");
    size_t segments = 0;
    for (const auto& s : mitsuba->shapes())
        if (const auto* c = dynamic_cast<const Curves*>(s.get())) segments += c->segment_count();
    EXPECT_EQ(segments, 2u + 1u + 3u + 2u);  // B-splines 5 and 4 points; polylines 4 and 3
}

}  // namespace
}  // namespace render
