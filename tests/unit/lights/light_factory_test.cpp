// make_light (core/lights/light_factory.h): every light type, environment maps from EXR and
// sRGB PNG files, and the error messages.

#include "core/lights/light_factory.h"

#include <OpenImageIO/imageio.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "core/lights/area_light.h"
#include "core/lights/constant_light.h"
#include "core/lights/directional_light.h"
#include "core/lights/envmap_light.h"
#include "core/lights/point_light.h"
#include "tests/support/light_fixtures.h"

namespace render::testing {
namespace {

// ---------------------------------------------------------------------------------------
// Factory

struct TempDir {
    std::filesystem::path path;
    TempDir() {
        path = std::filesystem::temp_directory_path() /
               ("light_factory_test_" + std::to_string(::getpid()));
        std::filesystem::create_directories(path);
    }
    ~TempDir() {
        std::error_code ec;
        std::filesystem::remove_all(path, ec);
    }
};

void write_exr(const std::filesystem::path& file, const std::vector<Rgb>& texels, int w, int h) {
    auto out = OIIO::ImageOutput::create(file.string());
    ASSERT_TRUE(out) << OIIO::geterror();
    OIIO::ImageSpec spec(w, h, 3, OIIO::TypeDesc::FLOAT);
    ASSERT_TRUE(out->open(file.string(), spec)) << out->geterror();
    ASSERT_TRUE(out->write_image(OIIO::TypeDesc::FLOAT, texels.data())) << out->geterror();
    out->close();
}

SourceLocation at(int line) {
    return SourceLocation{"scene.xml", line};
}

std::string factory_error(const Properties& props, const Shape* shape = nullptr,
                          const std::filesystem::path& dir = ".") {
    try {
        make_light(props, shape, dir);
    } catch (const SceneError& e) {
        return e.what();
    }
    return "(no error)";
}

TEST(LightFactory, BuildsEveryType) {
    Parallelogram shape = ceiling();
    Properties area("emitter", "area", at(3));
    area.set("radiance", Rgb(1, 2, 3), at(4));
    auto a = make_light(area, &shape, ".");
    EXPECT_NE(dynamic_cast<AreaLight*>(a.get()), nullptr);
    area.check_all_used();

    Properties point("emitter", "point", at(5));
    point.set("to_world", Transform::translate(Vec3(1, 2, 3)), at(6));
    point.set("intensity", Rgb(7), at(7));
    auto p = make_light(point, nullptr, ".");
    ASSERT_NE(dynamic_cast<PointLight*>(p.get()), nullptr);
    EXPECT_EQ(dynamic_cast<PointLight*>(p.get())->position(), Vec3(1, 2, 3));
    point.check_all_used();

    Properties directional("emitter", "directional", at(8));
    directional.set("to_world", Transform::rotate(Vec3(1, 0, 0), 90), at(9));
    directional.set("irradiance", 2.0f, at(10));
    auto d = make_light(directional, nullptr, ".");
    ASSERT_NE(dynamic_cast<DirectionalLight*>(d.get()), nullptr);
    // +z rotated by 90 degrees about +x is -y.
    EXPECT_NEAR(dynamic_cast<DirectionalLight*>(d.get())->direction().y, -1.0f, 1e-6f);
    directional.check_all_used();

    Properties constant("emitter", "constant", at(11));
    constant.set("radiance", Rgb(0.5f), at(12));
    auto c = make_light(constant, nullptr, ".");
    EXPECT_TRUE(c->is_infinite_background());
    constant.check_all_used();
}

TEST(LightFactory, LoadsAnEnvmapFromAnExrFile) {
    TempDir dir;
    const int w = 8, h = 4;
    std::vector<Rgb> t = pattern(w, h, 1e6f);
    write_exr(dir.path / "sky.exr", t, w, h);
    Properties props("emitter", "envmap", at(20));
    props.set("filename", std::string("sky.exr"), at(21));  // relative to the scene folder
    props.set("scale", 2.0f, at(22));
    props.set("to_world", Transform::rotate(Vec3(0, 1, 0), 90), at(23));
    auto light = make_light(props, nullptr, dir.path);
    props.check_all_used();
    auto* env = dynamic_cast<EnvmapLight*>(light.get());
    ASSERT_NE(env, nullptr);
    EXPECT_EQ(env->width(), w);
    EXPECT_EQ(env->height(), h);
    Frame frame = *EnvmapLight::rotation_frame(Transform::rotate(Vec3(0, 1, 0), 90));
    for (int row = 0; row < h; ++row)
        for (int col = 0; col < w; ++col) {
            Vec3 d = frame.to_world(EnvmapLight::uv_to_direction(texel_center(col, row, w, h)));
            expect_close(env->radiance(Vec3(0.0f), Vec3(0.0f), d).radiance,
                         t[size_t(row * w + col)] * 2.0f);
        }
}

TEST(LightFactory, LoadsAnSrgbPngAsLinear) {
    TempDir dir;
    const std::string file = (dir.path / "sky.png").string();
    {
        auto out = OIIO::ImageOutput::create(file);
        ASSERT_TRUE(out);
        OIIO::ImageSpec spec(2, 1, 3, OIIO::TypeDesc::UINT8);
        ASSERT_TRUE(out->open(file, spec));
        const unsigned char pixels[6] = {128, 128, 128, 255, 0, 255};
        ASSERT_TRUE(out->write_image(OIIO::TypeDesc::UINT8, pixels));
        out->close();
    }
    Properties props("emitter", "envmap", at(40));
    props.set("filename", file, at(41));
    auto light = make_light(props, nullptr, "/unused");
    // u in [0, 1/2) is the left pixel: sRGB 128/255 decodes to 0.2158.
    Vec3 left = EnvmapLight::uv_to_direction(Vec2(0.25f, 0.5f));
    Vec3 right = EnvmapLight::uv_to_direction(Vec2(0.75f, 0.5f));
    expect_close(light->radiance(Vec3(0.0f), Vec3(0.0f), left).radiance, Rgb(0.21586f), 1e-3f);
    EXPECT_EQ(light->radiance(Vec3(0.0f), Vec3(0.0f), right).radiance, Rgb(1, 0, 1));
}

TEST(LightFactory, ErrorMessages) {
    Properties unknown("emitter", "projector", at(12));
    EXPECT_EQ(factory_error(unknown),
              "scene.xml:12: unknown emitter type \"projector\" (supported: area, point, spot, "
              "directional, constant, envmap)");

    Properties area("emitter", "area", at(13));
    EXPECT_NE(factory_error(area).find("scene.xml:13: emitter \"area\" must be nested inside a "
                                       "shape"),
              std::string::npos)
        << factory_error(area);

    Parallelogram shape = ceiling();
    Properties nested("emitter", "point", at(14));
    EXPECT_NE(factory_error(nested, &shape).find("cannot be nested"), std::string::npos);

    Properties negative("emitter", "area", at(15));
    negative.set("radiance", Rgb(1, -2, 3), at(16));
    std::string message = factory_error(negative, &shape);
    EXPECT_NE(message.find("scene.xml:16"), std::string::npos) << message;
    EXPECT_NE(message.find("\"radiance\""), std::string::npos) << message;
    EXPECT_NE(message.find("non-negative"), std::string::npos) << message;

    Properties nan("emitter", "point", at(17));
    nan.set("intensity", Rgb(std::nanf("")), at(18));
    EXPECT_NE(factory_error(nan).find("scene.xml:18"), std::string::npos);

    Properties both("emitter", "point", at(19));
    both.set("position", Vec3(0.0f), at(20));
    both.set("to_world", Transform(), at(21));
    EXPECT_NE(factory_error(both).find("not both"), std::string::npos);

    Properties zero("emitter", "directional", at(22));
    zero.set("direction", Vec3(0.0f), at(23));
    EXPECT_NE(factory_error(zero).find("scene.xml:23"), std::string::npos);
}

TEST(LightFactory, EnvmapFileErrors) {
    TempDir dir;
    Properties missing("emitter", "envmap", at(30));
    missing.set("filename", std::string("textures/nothere.exr"), at(31));
    std::string message = factory_error(missing, nullptr, dir.path);
    EXPECT_NE(message.find("scene.xml:31"), std::string::npos) << message;
    EXPECT_NE(message.find((dir.path / "textures/nothere.exr").string()), std::string::npos)
        << message;
    EXPECT_NE(message.find("not found"), std::string::npos) << message;

    {
        std::ofstream garbage(dir.path / "bad.exr");
        garbage << "this is not an image";
    }
    Properties bad("emitter", "envmap", at(32));
    bad.set("filename", (dir.path / "bad.exr").string(), at(33));
    message = factory_error(bad, nullptr, "/elsewhere");
    EXPECT_NE(message.find("scene.xml:33"), std::string::npos) << message;
    EXPECT_NE(message.find("cannot read environment map \"" + (dir.path / "bad.exr").string()),
              std::string::npos)
        << message;

    write_exr(dir.path / "ok.exr", std::vector<Rgb>(8, Rgb(1.0f)), 4, 2);
    Properties skew("emitter", "envmap", at(34));
    skew.set("filename", std::string("ok.exr"), at(35));
    skew.set("to_world", Transform::scale(Vec3(1, 2, 1)), at(36));
    message = factory_error(skew, nullptr, dir.path);
    EXPECT_NE(message.find("scene.xml:36"), std::string::npos) << message;
    EXPECT_NE(message.find("rotation"), std::string::npos) << message;

    Properties scale("emitter", "envmap", at(37));
    scale.set("filename", std::string("ok.exr"), at(38));
    scale.set("scale", -1.0f, at(39));
    EXPECT_NE(factory_error(scale, nullptr, dir.path).find("scene.xml:39"), std::string::npos);
}

}  // namespace
}  // namespace render::testing
