// The loaders' side of pbrt-v4's `diffusetransmission`, thin-lens cameras in both formats and
// the shipped scenes of these features (scenes/tests/): what each parameter becomes.

#include <gtest/gtest.h>

#include <string>

#include "core/materials/diffuse_transmission.h"
#include "core/scene/loader/scene_loader.h"
#include "core/scene/pbrt/scene_loader.h"
#include "core/scene/scene.h"
#include "core/shapes/alpha_cutout.h"

namespace render {
namespace {

const char* kTriangle = "Shape \"trianglemesh\" \"point3 P\" [0 0 0 1 0 0 0 1 0]\n";

TEST(SceneFeatures, PbrtDiffuseTransmission) {
    auto scene = pbrt::load_scene_from_string(
        std::string("WorldBegin\nMaterial \"diffusetransmission\" \"rgb reflectance\" [0.2 0.4 "
                    "0.6] \"rgb transmittance\" [0.5 0.5 0.5] \"float scale\" [2]\n") +
            kTriangle + "Material \"diffusetransmission\"\n" + kTriangle,
        ".");
    ASSERT_EQ(scene->shapes().size(), 2u);
    const auto* scaled = dynamic_cast<const DiffuseTransmissionBsdf*>(scene->shapes()[0]->bsdf);
    ASSERT_NE(scaled, nullptr) << scene->shapes()[0]->bsdf->to_string();
    EXPECT_NEAR(scaled->reflectance().g, 0.8f, 1e-6);
    EXPECT_EQ(scaled->transmittance(), Rgb(1.0f));  // 2 x 0.5, clamped at 1
    const auto* plain = dynamic_cast<const DiffuseTransmissionBsdf*>(scene->shapes()[1]->bsdf);
    ASSERT_NE(plain, nullptr);
    EXPECT_EQ(plain->reflectance(), Rgb(0.25f));  // pbrt-v4's defaults
    EXPECT_EQ(plain->transmittance(), Rgb(0.25f));
}

TEST(SceneFeatures, PbrtThinLens) {
    auto scene = pbrt::load_scene_from_string(
        "Camera \"perspective\" \"float lensradius\" [0.25] \"float focaldistance\" [7]\n"
        "WorldBegin\n" +
            std::string(kTriangle),
        ".");
    EXPECT_TRUE(scene->camera().has_lens());
    EXPECT_FLOAT_EQ(scene->camera().lens_radius(), 0.25f);
    EXPECT_FLOAT_EQ(scene->camera().focus_distance(), 7.0f);
    // A resolution change keeps the lens.
    EXPECT_TRUE(scene->camera().with_resolution(8, 8).has_lens());
    auto pinhole = pbrt::load_scene_from_string("WorldBegin\n" + std::string(kTriangle), ".");
    EXPECT_FALSE(pinhole->camera().has_lens());
}

TEST(SceneFeatures, MitsubaThinLens) {
    auto scene = load_scene_from_string(R"(<scene version="3.0.0">
  <sensor type="thinlens">
    <float name="aperture_radius" value="0.1"/>
    <float name="focus_distance" value="3"/>
    <float name="fov" value="30"/>
  </sensor>
</scene>)",
                                        ".");
    EXPECT_TRUE(scene->camera().has_lens());
    EXPECT_FLOAT_EQ(scene->camera().lens_radius(), 0.1f);
    EXPECT_FLOAT_EQ(scene->camera().focus_distance(), 3.0f);
    // A perspective sensor's focus_distance stays without effect.
    auto pinhole = load_scene_from_string(R"(<scene version="3.0.0">
  <sensor type="perspective"><float name="focus_distance" value="3"/></sensor>
</scene>)",
                                          ".");
    EXPECT_FALSE(pinhole->camera().has_lens());
}

TEST(SceneFeatures, ShippedFeatureScenesLoad) {
    const std::string dir = std::string(RENDER_SOURCE_DIR) + "/scenes/tests/";
    auto nested = load_scene(dir + "nested-media.xml");
    int declaring = 0;
    for (const auto& s : nested->shapes()) declaring += s->interior != nullptr;
    EXPECT_EQ(declaring, 2);
    EXPECT_TRUE(load_scene(dir + "thinlens.xml")->camera().has_lens());
    EXPECT_TRUE(pbrt::load_scene(dir + "thinlens.pbrt")->camera().has_lens());
    auto transmission = pbrt::load_scene(dir + "diffusetransmission.pbrt");
    int transmitting = 0;
    for (const auto& s : transmission->shapes())
        transmitting += dynamic_cast<const DiffuseTransmissionBsdf*>(s->bsdf) != nullptr;
    EXPECT_EQ(transmitting, 2);
    auto alpha = pbrt::load_scene(dir + "alpha.pbrt");
    int cut = 0;
    for (const auto& s : alpha->shapes()) cut += s->alpha != nullptr;
    EXPECT_EQ(cut, 2);
}

}  // namespace
}  // namespace render
