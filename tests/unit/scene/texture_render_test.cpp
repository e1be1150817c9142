// Textures in whole renders: a checkerboard plane shows its two colours where they belong, and a
// material whose texture is a constant renders bit-identically to the same constant given as a
// plain value, with every algorithm (the per-hit BSDF must be exactly the plain one, and must
// stay alive in stored light vertices).

#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "core/render/render_iterations.h"
#include "core/scene/loader/scene_loader.h"
#include "tests/support/algorithms.h"

namespace render {
namespace {

// The rectangle [-1, 1]^2 (uv = ((x + 1) / 2, (y + 1) / 2)) seen from +z by a camera with +y
// up, filling the 32 x 32 image; lit only by a constant environment of radiance 1.
std::string checker_plane_scene() {
    return R"(<scene version="3.0.0">
  <sensor type="perspective">
    <float name="fov" value="30"/>
    <transform name="to_world"><lookat origin="0, 0, 3" target="0, 0, 0" up="0, 1, 0"/></transform>
    <film type="hdrfilm"><integer name="width" value="32"/><integer name="height" value="32"/></film>
  </sensor>
  <emitter type="constant"><rgb name="radiance" value="1"/></emitter>
  <shape type="rectangle">
    <bsdf type="diffuse">
      <texture type="checkerboard" name="reflectance">
        <rgb name="color0" value="0.8, 0.4, 0.1"/>
        <rgb name="color1" value="0.1, 0.3, 0.6"/>
      </texture>
    </bsdf>
  </shape>
</scene>)";
}

struct BlockMean {
    Rgb mean;
    Rgb standard_error;
};

// Mean and standard error of the pixels x0..x0+7, y0..y0+7 (rows top to bottom). Pixels of a
// path-traced image are independent, so their spread gives the standard error of the mean.
BlockMean block(const IterationResult& r, int width, int x0, int y0) {
    BlockMean out;
    for (int c = 0; c < 3; ++c) {
        double sum = 0, sum2 = 0;
        const int n = 64;
        for (int y = y0; y < y0 + 8; ++y)
            for (int x = x0; x < x0 + 8; ++x) {
                const double v =
                    r.sum.channel(size_t(y) * size_t(width) + size_t(x), c) / double(r.count);
                sum += v;
                sum2 += v * v;
            }
        const double mean = sum / n;
        const double var = std::max(0.0, (sum2 - n * mean * mean) / (n - 1));
        out.mean[c] = float(mean);
        out.standard_error[c] = float(std::sqrt(var / n));
    }
    return out;
}

TEST(TextureRender, CheckerboardPlaneShowsBothColours) {
    auto scene = load_scene_from_string(checker_plane_scene(), ".");
    RenderSettings settings;
    settings.algorithm = "pt";
    settings.seed = 11;
    const IterationResult r = render_iterations(*scene, settings, 0, IterationRange{1, 17});
    ASSERT_EQ(r.stats.non_finite, 0u);
    // A Lambertian plane under a unit environment that fills its upper hemisphere reflects
    // L = reflectance * 1 (irradiance pi, times reflectance / pi). The image's right is world
    // +x and its top world +y, so the top-right and bottom-left quadrants have u and v on the
    // same side of 1/2 (color0); blocks 4 pixels in from the seams avoid the squares' edges.
    const Rgb color0(0.8f, 0.4f, 0.1f), color1(0.1f, 0.3f, 0.6f);
    struct Quadrant {
        const char* name;
        int x0, y0;
        Rgb expected;
    };
    for (const Quadrant& q :
         {Quadrant{"top-right", 20, 4, color0}, Quadrant{"bottom-left", 4, 20, color0},
          Quadrant{"top-left", 4, 4, color1}, Quadrant{"bottom-right", 20, 20, color1}}) {
        const BlockMean b = block(r, 32, q.x0, q.y0);
        for (int c = 0; c < 3; ++c) {
            // 5 standard errors: a false failure has probability ~6e-7 per check. The
            // colours differ by at least 0.1 per channel, far above it (asserted below).
            EXPECT_NEAR(b.mean[c], q.expected[c], 5 * b.standard_error[c] + 1e-4f)
                << q.name << " channel " << c << ", SE " << b.standard_error[c];
            EXPECT_LT(5 * b.standard_error[c], 0.05f) << q.name << " channel " << c;
        }
    }
}

// Two planes and a spherical light; each material and the light once with plain values and
// once with a checkerboard whose two colours are those values (so textured, and constant).
std::string mixed_scene(bool textured) {
    auto value = [&](const std::string& name, const std::string& v, bool rgb) {
        const std::string tag = rgb ? "rgb" : "float";
        if (!textured) return "<" + tag + " name=\"" + name + "\" value=\"" + v + "\"/>";
        return "<texture type=\"checkerboard\" name=\"" + name + "\"><" + tag +
               " name=\"color0\" value=\"" + v + "\"/><" + tag + " name=\"color1\" value=\"" + v +
               "\"/></texture>";
    };
    return R"(<scene version="3.0.0">
  <sensor type="perspective">
    <float name="fov" value="50"/>
    <transform name="to_world"><lookat origin="0, -2, 2.5" target="0, 0, 0" up="0, 0, 1"/></transform>
    <film type="hdrfilm"><integer name="width" value="16"/><integer name="height" value="16"/></film>
  </sensor>
  <shape type="sphere">
    <point name="center" value="0.6, 0.3, 1.2"/><float name="radius" value="0.2"/>
    <emitter type="area">)" +
           value("radiance", "12, 10, 8", true) + R"(</emitter>
  </shape>
  <shape type="rectangle">
    <transform name="to_world"><scale value="2"/></transform>
    <bsdf type="diffuse">)" +
           value("reflectance", "0.3, 0.5, 0.7", true) + R"(</bsdf>
  </shape>
  <shape type="rectangle">
    <transform name="to_world"><rotate x="1" angle="90"/><translate y="1"/></transform>
    <bsdf type="twosided"><bsdf type="plastic">)" +
           value("diffuse_reflectance", "0.6, 0.2, 0.2", true) + R"(</bsdf></bsdf>
  </shape>
  <shape type="sphere">
    <point name="center" value="-0.5, 0, 0.4"/><float name="radius" value="0.4"/>
    <bsdf type="roughconductor"><string name="material" value="Au"/>)" +
           value("alpha", "0.3", false) + R"(</bsdf>
  </shape>
</scene>)";
}

class ConstantTextureRender : public ::testing::TestWithParam<std::string> {};

TEST_P(ConstantTextureRender, RendersBitIdenticallyToThePlainValue) {
    auto plain = load_scene_from_string(mixed_scene(false), ".");
    auto textured = load_scene_from_string(mixed_scene(true), ".");
    ASSERT_FALSE(plain->shapes()[1]->bsdf->varies());
    ASSERT_TRUE(textured->shapes()[1]->bsdf->varies());
    ASSERT_NE(textured->lights()[0]->to_string().find("mean of checkerboard"), std::string::npos);
    RenderSettings settings = testing::algorithm_settings(GetParam());
    settings.seed = 5;
    const IterationResult a = render_iterations(*plain, settings, 0, IterationRange{1, 4});
    const IterationResult b = render_iterations(*textured, settings, 0, IterationRange{1, 4});
    ASSERT_EQ(a.stats.rays, b.stats.rays);
    double total = 0;
    for (size_t i = 0; i < a.sum.values().size(); ++i) {
        ASSERT_EQ(a.sum.values()[i], b.sum.values()[i]) << "value " << i;
        total += a.sum.values()[i];
    }
    EXPECT_GT(total, 0.0);  // the scene is lit: the comparison is not of two black images
}

INSTANTIATE_TEST_SUITE_P(Algorithms, ConstantTextureRender,
                         ::testing::ValuesIn(testing::physically_based_algorithms()));

}  // namespace
}  // namespace render
