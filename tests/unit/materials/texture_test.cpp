// Textures: bitmap lookups (bilinear and nearest, the three wrap modes, sRGB decoding of integer
// files and `raw`), checkerboard values, to_uv transforms, and the loader's errors. Expected
// values are computed here by hand from Mitsuba's definitions, not by the code under test.

#include <gtest/gtest.h>

#include <unistd.h>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "core/base/error.h"
#include "core/image/exr_io.h"
#include "core/image/image_plugin.h"
#include "core/image/srgb.h"
#include "core/textures/bitmap_texture.h"
#include "core/textures/checkerboard_texture.h"
#include "core/textures/constant_texture.h"
#include "core/textures/texture_factory.h"

namespace render {
namespace {

namespace fs = std::filesystem;

// Lookups are a few float multiply-adds of exactly representable inputs: 1e-5 absolute covers
// their rounding and nothing else.
constexpr float kTol = 1e-5f;

#define EXPECT_RGB_NEAR(actual, expected, tol)              \
    do {                                                    \
        const Rgb a_ = (actual), e_ = (expected);           \
        EXPECT_NEAR(a_.r, e_.r, tol) << a_ << " vs " << e_; \
        EXPECT_NEAR(a_.g, e_.g, tol) << a_ << " vs " << e_; \
        EXPECT_NEAR(a_.b, e_.b, tol) << a_ << " vs " << e_; \
    } while (0)

#define EXPECT_CONTAINS(haystack, needle) \
    EXPECT_NE(std::string(haystack).find(needle), std::string::npos) << (haystack)

// 3 x 2 texels, value x + 10 y in every channel: a swapped axis or an off-by-one texel shows.
BitmapTexture grid(BitmapTexture::Filter filter, BitmapTexture::Wrap wrap,
                   const UvTransform& to_uv = UvTransform()) {
    std::vector<Rgb> texels;
    for (int y = 0; y < 2; ++y)
        for (int x = 0; x < 3; ++x) texels.push_back(Rgb(float(x + 10 * y)));
    return BitmapTexture(std::move(texels), 3, 2, filter, wrap, to_uv, "grid");
}

float at(const Texture& t, float u, float v) {
    return t.eval(Vec2(u, v)).r;
}

TEST(BitmapTexture, BilinearInterpolatesBetweenTexelCentres) {
    const BitmapTexture t = grid(BitmapTexture::Filter::Bilinear, BitmapTexture::Wrap::Clamp);
    // Texel (i, j) is centred at ((i + 0.5) / 3, (j + 0.5) / 2); v = 0 is the first row.
    EXPECT_NEAR(at(t, 0.5f / 3, 0.25f), 0.0f, kTol);
    EXPECT_NEAR(at(t, 2.5f / 3, 0.25f), 2.0f, kTol);
    EXPECT_NEAR(at(t, 0.5f / 3, 0.75f), 10.0f, kTol);
    // A quarter of the way from texel 0 to texel 1, half-way down: 0.25 + 10 * 0.5.
    EXPECT_NEAR(at(t, 0.75f / 3, 0.5f), 5.25f, kTol);
    // Mid-image: half-way between columns 1 and 2 only at u = 2/3.
    EXPECT_NEAR(at(t, 2.0f / 3, 0.5f), 1.5f + 5.0f, kTol);
}

TEST(BitmapTexture, WrapModesDecideTheTexelsBeyondTheEdge) {
    // At u = 0 the lookup falls half-way between column -1 and column 0 (row 0).
    const float u = 0.0f, v = 0.25f;
    // repeat: column -1 is column 2.
    EXPECT_NEAR(at(grid(BitmapTexture::Filter::Bilinear, BitmapTexture::Wrap::Repeat), u, v), 1.0f,
                kTol);
    // mirror: column -1 is column 0.
    EXPECT_NEAR(at(grid(BitmapTexture::Filter::Bilinear, BitmapTexture::Wrap::Mirror), u, v), 0.0f,
                kTol);
    // clamp: column 0.
    EXPECT_NEAR(at(grid(BitmapTexture::Filter::Bilinear, BitmapTexture::Wrap::Clamp), u, v), 0.0f,
                kTol);

    // Nearest lookups outside [0, 1]: u = 1.2 is column 0 repeated, column 2 mirrored (3.6 ->
    // index 3, the mirror image of 2) and column 2 clamped; u = -0.1 is column 2, 0, 0.
    const auto nearest = [](BitmapTexture::Wrap w) {
        return grid(BitmapTexture::Filter::Nearest, w);
    };
    EXPECT_NEAR(at(nearest(BitmapTexture::Wrap::Repeat), 1.2f, 0.25f), 0.0f, 0.0f);
    EXPECT_NEAR(at(nearest(BitmapTexture::Wrap::Mirror), 1.2f, 0.25f), 2.0f, 0.0f);
    EXPECT_NEAR(at(nearest(BitmapTexture::Wrap::Clamp), 1.2f, 0.25f), 2.0f, 0.0f);
    EXPECT_NEAR(at(nearest(BitmapTexture::Wrap::Repeat), -0.1f, 0.25f), 2.0f, 0.0f);
    EXPECT_NEAR(at(nearest(BitmapTexture::Wrap::Mirror), -0.1f, 0.25f), 0.0f, 0.0f);
    EXPECT_NEAR(at(nearest(BitmapTexture::Wrap::Clamp), -0.1f, 0.25f), 0.0f, 0.0f);
    // v wraps the same way: v = 1.3 is row 0 repeated, row 1 mirrored (2.6 -> index 2).
    EXPECT_NEAR(at(nearest(BitmapTexture::Wrap::Repeat), 0.1f, 1.3f), 0.0f, 0.0f);
    EXPECT_NEAR(at(nearest(BitmapTexture::Wrap::Mirror), 0.1f, 1.3f), 10.0f, 0.0f);
    // Repeating is periodic over any number of tiles, including huge coordinates.
    EXPECT_NEAR(at(grid(BitmapTexture::Filter::Bilinear, BitmapTexture::Wrap::Repeat),
                   0.75f / 3 + 4096.0f, 0.5f - 2048.0f),
                5.25f, 1e-3f);  // 4096 + 0.25 keeps ~3 decimal digits of the fraction in float
}

TEST(BitmapTexture, NearestTakesTheTexelContainingUv) {
    const BitmapTexture t = grid(BitmapTexture::Filter::Nearest, BitmapTexture::Wrap::Repeat);
    EXPECT_NEAR(at(t, 0.01f, 0.01f), 0.0f, 0.0f);
    EXPECT_NEAR(at(t, 0.34f, 0.01f), 1.0f, 0.0f);
    EXPECT_NEAR(at(t, 0.99f, 0.99f), 12.0f, 0.0f);
    EXPECT_NEAR(at(t, 0.66f, 0.51f), 11.0f, 0.0f);
}

TEST(BitmapTexture, MeanAndRange) {
    const BitmapTexture t = grid(BitmapTexture::Filter::Bilinear, BitmapTexture::Wrap::Repeat);
    EXPECT_NEAR(t.mean().r, (0 + 1 + 2 + 10 + 11 + 12) / 6.0f, kTol);
    EXPECT_EQ(t.min_value(), 0.0f);
    EXPECT_EQ(t.max_value(), 12.0f);
}

TEST(BitmapTexture, ToUvScalesTranslatesAndRotates) {
    // to_uv = translate(0.5 / 3, 0) * scale(0.5): uv (0, 0.5) looks up (1/6, 0.25) = texel (0, 0).
    const Transform scale_then_shift =
        Transform::translate(Vec3(0.5f / 3, 0, 0)) * Transform::scale(Vec3(0.5f, 0.5f, 1));
    const BitmapTexture t = grid(BitmapTexture::Filter::Nearest, BitmapTexture::Wrap::Clamp,
                                 UvTransform(scale_then_shift));
    EXPECT_NEAR(at(t, 0.0f, 0.5f), 0.0f, 0.0f);
    EXPECT_NEAR(at(t, 1.2f, 1.5f), 12.0f, 0.0f);  // looks up (0.6 + 1/6, 0.75)
    // A rotation by 90 degrees about z maps (u, v) to (-v, u).
    const BitmapTexture r = grid(BitmapTexture::Filter::Nearest, BitmapTexture::Wrap::Clamp,
                                 UvTransform(Transform::rotate(Vec3(0, 0, 1), 90.0f)));
    EXPECT_NEAR(at(r, 0.9f, -0.9f), 12.0f, 0.0f);  // looks up (0.9, 0.9)
    EXPECT_NEAR(at(r, 0.9f, -0.1f), 10.0f, 0.0f);  // looks up (0.1, 0.9)
}

TEST(Texture, SingleValueIsTheLuminanceOrTheGreyValue) {
    // Roughness from a texture, as Mitsuba's eval_1: a grey value exactly (so a constant
    // texture gives the same BSDF as the plain number), a colour's Rec. 709 luminance.
    EXPECT_EQ(ConstantTexture(Rgb(0.3f)).eval_1(Vec2()), 0.3f);
    EXPECT_NEAR(ConstantTexture(Rgb(0.2f, 0.5f, 0.9f)).eval_1(Vec2()),
                0.212671f * 0.2f + 0.715160f * 0.5f + 0.072169f * 0.9f, 1e-6f);
}

class TextureFiles : public ::testing::Test {
  protected:
    void SetUp() override {
        dir_ = fs::temp_directory_path() /
               ("texture_test_" + std::to_string(::getpid()) + "_" +
                ::testing::UnitTest::GetInstance()->current_test_info()->name());
        fs::create_directories(dir_);
    }
    void TearDown() override {
        std::error_code ec;
        fs::remove_all(dir_, ec);
    }

    // A 2 x 1 8-bit PNG, written through the image plugin as any user's file would be.
    fs::path write_png(const std::string& name, const std::vector<unsigned char>& rgb) {
        const fs::path file = dir_ / name;
        char error[512] = "";
        const RenderImagePlugin& plugin = image_plugin("to write the test's PNG");
        EXPECT_EQ(plugin.write_rgb8(file.c_str(), 2, 1, rgb.data(), error, sizeof error), 0)
            << error;
        return file;
    }

    std::shared_ptr<const Texture> bitmap(const fs::path& file, bool raw) {
        Properties props("texture", "bitmap", SourceLocation{"scene.xml", 7});
        props.set("filename", file.string(), SourceLocation{"scene.xml", 8});
        props.set("raw", raw, SourceLocation{"scene.xml", 9});
        props.set("filter_type", std::string("nearest"), SourceLocation{"scene.xml", 10});
        std::shared_ptr<const Texture> t = make_texture(props);
        props.check_all_used();
        return t;
    }

    fs::path dir_;
};

TEST_F(TextureFiles, PngIsSrgbDecodedUnlessRaw) {
    const fs::path png = write_png("two.png", {0, 64, 128, 255, 200, 13});
    const std::shared_ptr<const Texture> decoded = bitmap(png, false);
    const std::shared_ptr<const Texture> raw = bitmap(png, true);
    // 8-bit values are k / 255; decoding applies the exact sRGB curve (1e-6: float rounding).
    const auto srgb = [](int k) { return srgb_to_linear(float(k) / 255.0f); };
    EXPECT_RGB_NEAR(decoded->eval(Vec2(0.25f, 0.5f)), Rgb(srgb(0), srgb(64), srgb(128)), 1e-6f);
    EXPECT_RGB_NEAR(decoded->eval(Vec2(0.75f, 0.5f)), Rgb(srgb(255), srgb(200), srgb(13)), 1e-6f);
    EXPECT_RGB_NEAR(raw->eval(Vec2(0.25f, 0.5f)), Rgb(0.0f, 64 / 255.0f, 128 / 255.0f), 1e-6f);
    EXPECT_RGB_NEAR(raw->eval(Vec2(0.75f, 0.5f)), Rgb(1.0f, 200 / 255.0f, 13 / 255.0f), 1e-6f);
    // The curve itself at a known point: sRGB 0.5 is linear 0.214.
    EXPECT_NEAR(srgb_to_linear(0.5f), 0.21404f, 1e-5f);
}

TEST_F(TextureFiles, ExrIsLinearWhetherRawOrNot) {
    const fs::path exr = dir_ / "two.exr";
    Image image(2, 1);
    image.set(0, Rgb(0.25f, 0.5f, 2.0f));
    image.set(1, Rgb(0.0f, 0.125f, 1.0f));
    write_exr(exr, image);
    for (bool raw : {false, true}) {
        const std::shared_ptr<const Texture> t = bitmap(exr, raw);
        EXPECT_RGB_NEAR(t->eval(Vec2(0.25f, 0.5f)), Rgb(0.25f, 0.5f, 2.0f), 0.0f);
        EXPECT_RGB_NEAR(t->eval(Vec2(0.75f, 0.5f)), Rgb(0.0f, 0.125f, 1.0f), 0.0f);
    }
}

TEST_F(TextureFiles, BadInputNamesTheFileTheLineAndThePlugin) {
    Properties missing("texture", "bitmap", SourceLocation{"scene.xml", 7});
    missing.set("filename", (dir_ / "nothere.png").string(), SourceLocation{"scene.xml", 8});
    try {
        make_texture(missing);
        ADD_FAILURE() << "a missing file was accepted";
    } catch (const SceneError& e) {
        EXPECT_CONTAINS(e.what(), "scene.xml:8");
        EXPECT_CONTAINS(e.what(), "texture \"bitmap\"");
        EXPECT_CONTAINS(e.what(), (dir_ / "nothere.png").string());
    }
    // Not an image at all: the plugin's reason, with the file and the line.
    const fs::path junk = dir_ / "junk.png";
    { std::ofstream(junk) << "not a png"; }
    Properties bad("texture", "bitmap", SourceLocation{"scene.xml", 3});
    bad.set("filename", junk.string(), SourceLocation{"scene.xml", 4});
    try {
        make_texture(bad);
        ADD_FAILURE() << "a broken file was accepted";
    } catch (const SceneError& e) {
        EXPECT_CONTAINS(e.what(), "scene.xml:4");
        EXPECT_CONTAINS(e.what(), junk.string());
    }
    Properties unknown("texture", "wood", SourceLocation{"scene.xml", 5});
    try {
        make_texture(unknown);
        ADD_FAILURE() << "an unknown texture type was accepted";
    } catch (const SceneError& e) {
        EXPECT_CONTAINS(e.what(), "scene.xml:5");
        EXPECT_CONTAINS(e.what(),
                        "unknown texture type \"wood\" (supported: bitmap, checkerboard)");
    }
    const fs::path png = write_png("ok.png", {1, 2, 3, 4, 5, 6});
    for (const auto& [name, value, message] :
         std::vector<std::tuple<std::string, std::string, std::string>>{
             {"wrap_mode", "wrap", "unknown wrap mode \"wrap\""},
             {"filter_type", "cubic", "unknown filter \"cubic\""},
             {"format", "fp8", "unknown format \"fp8\""}}) {
        Properties p("texture", "bitmap", SourceLocation{"scene.xml", 1});
        p.set("filename", png.string(), SourceLocation{"scene.xml", 2});
        p.set(name, value, SourceLocation{"scene.xml", 6});
        try {
            make_texture(p);
            ADD_FAILURE() << name << " " << value << " was accepted";
        } catch (const SceneError& e) {
            EXPECT_CONTAINS(e.what(), "scene.xml:6");
            EXPECT_CONTAINS(e.what(), message);
        }
    }
}

std::shared_ptr<const Texture> checkerboard(const Transform* to_uv) {
    Properties props("texture", "checkerboard", SourceLocation{"scene.xml", 1});
    props.set("color0", Rgb(0.1f, 0.2f, 0.3f), SourceLocation{"scene.xml", 2});
    props.set("color1", 0.7f, SourceLocation{"scene.xml", 3});
    if (to_uv) props.set("to_uv", *to_uv, SourceLocation{"scene.xml", 4});
    std::shared_ptr<const Texture> t = make_texture(props);
    props.check_all_used();
    return t;
}

TEST(CheckerboardTexture, FourSquaresPerUnitOfUv) {
    const Rgb c0(0.1f, 0.2f, 0.3f), c1(0.7f);
    const std::shared_ptr<const Texture> t = checkerboard(nullptr);
    // Mitsuba: color0 where frac(u) > 1/2 and frac(v) > 1/2 agree.
    EXPECT_RGB_NEAR(t->eval(Vec2(0.25f, 0.25f)), c0, 0.0f);
    EXPECT_RGB_NEAR(t->eval(Vec2(0.75f, 0.75f)), c0, 0.0f);
    EXPECT_RGB_NEAR(t->eval(Vec2(0.75f, 0.25f)), c1, 0.0f);
    EXPECT_RGB_NEAR(t->eval(Vec2(0.25f, 0.75f)), c1, 0.0f);
    EXPECT_RGB_NEAR(t->eval(Vec2(1.25f, -0.25f)), c1, 0.0f);  // periodic, negative too
    EXPECT_RGB_NEAR(t->eval(Vec2(0.5f, 0.5f)), c0, 0.0f);     // 1/2 counts as the low half
    EXPECT_RGB_NEAR(t->mean(), (c0 + c1) * 0.5f, kTol);
    EXPECT_NEAR(t->min_value(), 0.1f, 0.0f);
    EXPECT_NEAR(t->max_value(), 0.7f, 0.0f);

    // Defaults: 0.4 and 0.2.
    Properties defaults("texture", "checkerboard", SourceLocation{"scene.xml", 1});
    const std::shared_ptr<const Texture> d = make_texture(defaults);
    EXPECT_RGB_NEAR(d->eval(Vec2(0.25f, 0.25f)), Rgb(0.4f), 0.0f);
    EXPECT_RGB_NEAR(d->eval(Vec2(0.75f, 0.25f)), Rgb(0.2f), 0.0f);
}

TEST(CheckerboardTexture, ToUvTransformsTheLookup) {
    const Rgb c0(0.1f, 0.2f, 0.3f), c1(0.7f);
    // scale 2: (0.3, 0.1) -> (0.6, 0.2), a color1 square.
    const Transform scale = Transform::scale(Vec3(2, 2, 1));
    EXPECT_RGB_NEAR(checkerboard(&scale)->eval(Vec2(0.3f, 0.1f)), c1, 0.0f);
    EXPECT_RGB_NEAR(checkerboard(nullptr)->eval(Vec2(0.3f, 0.1f)), c0, 0.0f);
    // translate by (0.5, 0): (0.25, 0.25) -> (0.75, 0.25).
    const Transform shift = Transform::translate(Vec3(0.5f, 0, 0));
    EXPECT_RGB_NEAR(checkerboard(&shift)->eval(Vec2(0.25f, 0.25f)), c1, 0.0f);
    // rotate 90 degrees about z: (0.25, 0.75) -> (-0.75, 0.25), whose fractions are both low.
    const Transform rotate = Transform::rotate(Vec3(0, 0, 1), 90.0f);
    EXPECT_RGB_NEAR(checkerboard(&rotate)->eval(Vec2(0.25f, 0.75f)), c0, 0.0f);
    // Only x/y and the translation of a 4x4 transform act on uv; z is dropped.
    const Transform with_z = Transform::translate(Vec3(0, 0, 5)) * Transform::scale(Vec3(1, 1, 3));
    EXPECT_RGB_NEAR(checkerboard(&with_z)->eval(Vec2(0.75f, 0.25f)), c1, 0.0f);
}

TEST(CheckerboardTexture, ColoursCanBeTextures) {
    // color0 a checkerboard of its own at four times the frequency, looked up at the same uv.
    Properties inner("texture", "checkerboard", SourceLocation{"scene.xml", 1});
    inner.set("color0", 1.0f, SourceLocation{"scene.xml", 2});
    inner.set("color1", 0.0f, SourceLocation{"scene.xml", 3});
    inner.set("to_uv", Transform::scale(Vec3(4, 4, 1)), SourceLocation{"scene.xml", 4});
    Properties outer("texture", "checkerboard", SourceLocation{"scene.xml", 5});
    outer.set("color0", make_texture(inner), SourceLocation{"scene.xml", 6});
    const std::shared_ptr<const Texture> t = make_texture(outer);
    // (0.1, 0.1): outer colour0 square; inner (0.4, 0.4): both low -> 1.
    EXPECT_RGB_NEAR(t->eval(Vec2(0.1f, 0.1f)), Rgb(1.0f), 0.0f);
    // (0.2, 0.1): inner (0.8, 0.4): mixed -> 0.
    EXPECT_RGB_NEAR(t->eval(Vec2(0.2f, 0.1f)), Rgb(0.0f), 0.0f);
    // (0.7, 0.1): outer colour1, the default 0.2.
    EXPECT_RGB_NEAR(t->eval(Vec2(0.7f, 0.1f)), Rgb(0.2f), 0.0f);
}

}  // namespace
}  // namespace render
