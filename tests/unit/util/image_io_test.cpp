// Image files: EXR written and read with OpenEXR (render_core), everything else through the
// image plugin (OpenImageIO, loaded on demand). The files must stay what OpenImageIO wrote
// before: same channels, same attributes, same pixels as OIIO reads them.

#include "core/image/exr_io.h"

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>
#include <OpenEXR/ImfStringAttribute.h>
#include <OpenImageIO/imageio.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <string>
#include <vector>

#include "core/lights/envmap_light.h"

namespace render {
namespace {

namespace OIIO = OIIO_NAMESPACE;

struct TempDir {
    std::filesystem::path path;
    TempDir() {
        path = std::filesystem::temp_directory_path() /
               ("image_io_test_" + std::to_string(::getpid()));
        std::filesystem::create_directories(path);
    }
    ~TempDir() {
        std::error_code ec;
        std::filesystem::remove_all(path, ec);
    }
};

Image ramp(int w, int h, float offset) {
    Image image(w, h);
    for (size_t i = 0; i < image.pixel_count(); ++i)
        image.set(i, Rgb(offset + 0.25f * float(i), -1.5f * float(i) + offset, 1e6f * offset));
    return image;
}

std::vector<NamedLayer> two_layers(int w, int h) {
    return {{"vcm.merging", ramp(w, h, 7.0f)}, {"bpt.s0t2", ramp(w, h, -3.0f)}};
}

std::map<std::string, std::string> some_metadata() {
    return {{"render:algorithm", "vcm"},
            {"render:scene", "/some/where/scene_v3.xml"},
            {"render:non_finite_samples_dropped", "0"},  // longer than 31 characters
            {"render:define:spp", "4 = four, with spaces"},
            {"render:empty", ""}};
}

// What core's write_exr wrote through OpenImageIO before it used OpenEXR directly.
void write_exr_with_oiio(const std::filesystem::path& file, const Image& image,
                         const std::map<std::string, std::string>& metadata,
                         const std::vector<NamedLayer>& layers) {
    auto out = OIIO::ImageOutput::create(file.string());
    ASSERT_TRUE(out) << OIIO::geterror();
    const int channels = 3 * int(1 + layers.size());
    OIIO::ImageSpec spec(image.width(), image.height(), channels, OIIO::TypeDesc::FLOAT);
    spec.channelnames = {"R", "G", "B"};
    for (const NamedLayer& layer : layers)
        for (const char* c : {".R", ".G", ".B"}) spec.channelnames.push_back(layer.name + c);
    spec.attribute("compression", "zip");
    for (const auto& [key, value] : metadata) spec.attribute(key, value);
    std::vector<float> pixels(image.pixel_count() * size_t(channels));
    for (size_t i = 0; i < image.pixel_count(); ++i) {
        float* dst = &pixels[i * size_t(channels)];
        for (int c = 0; c < 3; ++c) dst[c] = image.data()[3 * i + c];
        for (size_t l = 0; l < layers.size(); ++l)
            for (int c = 0; c < 3; ++c) dst[3 * (l + 1) + c] = layers[l].image.data()[3 * i + c];
    }
    ASSERT_TRUE(out->open(file.string(), spec)) << out->geterror();
    ASSERT_TRUE(out->write_image(OIIO::TypeDesc::FLOAT, pixels.data())) << out->geterror();
    ASSERT_TRUE(out->close());
}

// A file as OpenImageIO sees it: channel names, all pixels, every attribute as text.
struct OiioView {
    std::vector<std::string> channels;
    std::vector<float> pixels;
    std::map<std::string, std::string> attributes;
    int width = 0, height = 0;
};

OiioView read_with_oiio(const std::filesystem::path& file) {
    OiioView v;
    auto in = OIIO::ImageInput::open(file.string());
    EXPECT_TRUE(in) << OIIO::geterror();
    if (!in) return v;
    const OIIO::ImageSpec& spec = in->spec();
    v.width = spec.width;
    v.height = spec.height;
    v.channels = spec.channelnames;
    v.pixels.resize(size_t(spec.width) * spec.height * spec.nchannels);
    EXPECT_TRUE(in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::FLOAT, v.pixels.data()));
    for (const auto& attr : spec.extra_attribs)
        v.attributes[attr.name().string()] = attr.get_string();
    in->close();
    return v;
}

TEST(ImageIo, ExrWithLayersAndAttributesReadsBackExactly) {
    TempDir dir;
    const int w = 5, h = 3;
    const Image image = ramp(w, h, 0.5f);
    const auto layers = two_layers(w, h);
    const auto metadata = some_metadata();
    const auto file = dir.path / "frame.exr";
    write_exr(file, image, metadata, layers);

    // Through core (OpenEXR): the main RGB, exactly, and every attribute.
    std::map<std::string, std::string> read_metadata;
    const Image back = read_image(file, &read_metadata);
    ASSERT_EQ(back.width(), w);
    ASSERT_EQ(back.height(), h);
    for (size_t i = 0; i < 3 * image.pixel_count(); ++i)
        EXPECT_EQ(back.data()[i], image.data()[i]) << i;
    for (const auto& [key, value] : metadata) EXPECT_EQ(read_metadata[key], value) << key;
    EXPECT_EQ(read_metadata.count("capDate"), 1u);

    // The file itself (OpenEXR): float channels R, G, B and NAME.R/G/B per layer, ZIP, and
    // the layers' pixels exactly.
    Imf::InputFile in(file.c_str());
    std::vector<std::string> names;
    for (auto it = in.header().channels().begin(); it != in.header().channels().end(); ++it) {
        names.push_back(it.name());
        EXPECT_EQ(it.channel().type, Imf::FLOAT) << it.name();
    }
    EXPECT_EQ(names,
              (std::vector<std::string>{"B", "G", "R", "bpt.s0t2.B", "bpt.s0t2.G", "bpt.s0t2.R",
                                        "vcm.merging.B", "vcm.merging.G", "vcm.merging.R"}));
    EXPECT_EQ(in.header().compression(), Imf::ZIP_COMPRESSION);
    std::vector<float> layer(size_t(w) * h * 3);
    for (const NamedLayer& l : layers) {
        Imf::FrameBuffer frame;
        for (int c = 0; c < 3; ++c)
            frame.insert(l.name + "." + "RGB"[c],
                         Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(layer.data() + c),
                                    3 * sizeof(float), 3 * sizeof(float) * w));
        in.setFrameBuffer(frame);
        in.readPixels(0, h - 1);
        for (size_t i = 0; i < layer.size(); ++i) EXPECT_EQ(layer[i], l.image.data()[i]) << i;
    }
}

TEST(ImageIo, OpenImageIoReadsTheExrAsItReadTheOneItWroteItself) {
    TempDir dir;
    const int w = 4, h = 6;
    const Image image = ramp(w, h, 2.0f);
    const auto layers = two_layers(w, h);
    const auto metadata = some_metadata();
    write_exr(dir.path / "openexr.exr", image, metadata, layers);
    write_exr_with_oiio(dir.path / "oiio.exr", image, metadata, layers);

    const OiioView now = read_with_oiio(dir.path / "openexr.exr");
    const OiioView before = read_with_oiio(dir.path / "oiio.exr");
    EXPECT_EQ(now.width, before.width);
    EXPECT_EQ(now.height, before.height);
    EXPECT_EQ(now.channels, before.channels);
    ASSERT_EQ(now.pixels.size(), before.pixels.size());
    for (size_t i = 0; i < now.pixels.size(); ++i) EXPECT_EQ(now.pixels[i], before.pixels[i]) << i;
    // Same attributes; only the date (written at a different second, perhaps) may differ.
    auto without_date = [](std::map<std::string, std::string> a) {
        EXPECT_EQ(a.count("DateTime"), 1u);
        a.erase("DateTime");
        return a;
    };
    EXPECT_EQ(without_date(now.attributes), without_date(before.attributes));
    // OpenImageIO does not report empty string attributes (in either file); the others are there.
    for (const auto& [key, value] : metadata) {
        if (!value.empty()) {
            EXPECT_EQ(now.attributes.count(key) ? now.attributes.at(key) : "(missing)", value)
                << key;
        }
    }
}

TEST(ImageIo, ReadsHalfRgbaAndGreyExr) {
    TempDir dir;
    const auto file = dir.path / "half.exr";
    {
        auto out = OIIO::ImageOutput::create(file.string());
        OIIO::ImageSpec spec(2, 1, 4, OIIO::TypeDesc::HALF);
        ASSERT_TRUE(out->open(file.string(), spec));
        const float pixels[8] = {0.5f, 1.0f, 2.0f, 0.25f, 4.0f, 8.0f, 16.0f, 1.0f};
        ASSERT_TRUE(out->write_image(OIIO::TypeDesc::FLOAT, pixels));
        out->close();
    }
    const Image rgba = read_image(file);
    EXPECT_EQ(rgba.data()[0], 0.5f);
    EXPECT_EQ(rgba.data()[2], 2.0f);
    EXPECT_EQ(rgba.data()[3], 4.0f);
    EXPECT_EQ(rgba.data()[5], 16.0f);

    const auto grey = dir.path / "grey.exr";
    {
        auto out = OIIO::ImageOutput::create(grey.string());
        OIIO::ImageSpec spec(2, 1, 1, OIIO::TypeDesc::FLOAT);
        spec.channelnames = {"Y"};
        ASSERT_TRUE(out->open(grey.string(), spec));
        const float pixels[2] = {3.0f, 5.0f};
        ASSERT_TRUE(out->write_image(OIIO::TypeDesc::FLOAT, pixels));
        out->close();
    }
    const Image g = read_image(grey);
    EXPECT_EQ(g.data()[0], 3.0f);
    EXPECT_EQ(g.data()[1], 3.0f);
    EXPECT_EQ(g.data()[5], 5.0f);
}

TEST(ImageIo, HdrAndPngGoThroughThePlugin) {
    TempDir dir;
    const auto hdr = dir.path / "sky.hdr";
    const float texels[6] = {1.0f, 0.5f, 0.25f, 8.0f, 2.0f, 0.0f};  // exact in RGBE
    {
        auto out = OIIO::ImageOutput::create(hdr.string());
        ASSERT_TRUE(out) << OIIO::geterror();
        OIIO::ImageSpec spec(2, 1, 3, OIIO::TypeDesc::FLOAT);
        ASSERT_TRUE(out->open(hdr.string(), spec));
        ASSERT_TRUE(out->write_image(OIIO::TypeDesc::FLOAT, texels));
        out->close();
    }
    const ImageFileData data = read_image_file(hdr);
    EXPECT_EQ(data.width, 2);
    EXPECT_EQ(data.height, 1);
    ASSERT_EQ(data.channels, 3);
    EXPECT_FALSE(data.integer_format);
    for (int i = 0; i < 6; ++i) EXPECT_EQ(data.pixels[size_t(i)], texels[i]) << i;

    // An .hdr environment map: radiance = texel * scale.
    auto light = EnvmapLight::load(hdr, 2.0f, Frame(Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(0, 0, 1)));
    const Vec3 right = EnvmapLight::uv_to_direction(Vec2(0.75f, 0.5f));
    EXPECT_EQ(light->radiance(Vec3(0.0f), Vec3(0.0f), right).radiance, Rgb(16.0f, 4.0f, 0.0f));

    // The PNG preview (written by the plugin) reads back as 8-bit sRGB.
    const auto png = dir.path / "preview.png";
    Image image(2, 1);
    image.set(0, Rgb(0.0f, 1.0f, 0.2158605f));
    image.set(1, Rgb(4.0f, 0.5f, 0.0f));
    write_png_preview(png, image, 0.5f);
    const ImageFileData preview = read_image_file(png);
    ASSERT_EQ(preview.channels, 3);
    EXPECT_TRUE(preview.integer_format);
    const float expected[6] = {0, 188, 92, 255, 137, 0};  // sRGB(v / 2) * 255, rounded
    for (int i = 0; i < 6; ++i)
        EXPECT_NEAR(preview.pixels[size_t(i)] * 255.0f, expected[i], 1e-3f) << i;
}

TEST(ImageIo, ErrorsNameTheFile) {
    TempDir dir;
    const auto bad = dir.path / "bad.exr";
    {
        std::ofstream garbage(bad);
        garbage << "this is not an image";
    }
    try {
        read_image(bad);
        FAIL() << "no exception";
    } catch (const std::runtime_error& e) {
        EXPECT_NE(std::string(e.what()).find("cannot read " + bad.string()), std::string::npos)
            << e.what();
    }
    const auto truncated = dir.path / "truncated.exr";
    write_exr(truncated, ramp(64, 64, 1.0f));
    std::filesystem::resize_file(truncated, 400);
    try {
        read_image(truncated);
        FAIL() << "no exception";
    } catch (const std::runtime_error& e) {
        EXPECT_NE(std::string(e.what()).find("cannot read " + truncated.string()),
                  std::string::npos)
            << e.what();
    }
    EXPECT_THROW(write_exr(dir.path / "no" / "such" / "dir.exr", ramp(2, 2, 0)),
                 std::runtime_error);
}

// With the plugin missing, reading a PNG fails with a message naming the plugin library; the
// EXR path does not need it. A fresh process (the plugin is loaded once per process).
TEST(ImageIoDeathTest, MissingPluginNamesItself) {
    GTEST_FLAG_SET(death_test_style, "threadsafe");
    TempDir dir;
    const auto exr = dir.path / "ok.exr";
    write_exr(exr, ramp(2, 2, 1.0f));
    const auto png = dir.path / "ok.png";
    {
        auto out = OIIO::ImageOutput::create(png.string());
        OIIO::ImageSpec spec(1, 1, 3, OIIO::TypeDesc::UINT8);
        ASSERT_TRUE(out->open(png.string(), spec));
        const unsigned char pixels[3] = {1, 2, 3};
        ASSERT_TRUE(out->write_image(OIIO::TypeDesc::UINT8, pixels));
        out->close();
    }
    EXPECT_EXIT(
        {
            setenv("RENDER_IMAGE_PLUGIN", "/nonexistent/librender_image_oiio.so", 1);
            read_image(exr);  // OpenEXR: fine without the plugin
            try {
                read_image(png);
            } catch (const std::exception& e) {
                std::cerr << e.what() << std::endl;
                std::exit(3);
            }
            std::exit(0);
        },
        testing::ExitedWithCode(3),
        "cannot read .*ok.png: the image plugin librender_image_oiio.so \\(OpenImageIO\\), "
        "needed to read .*ok.png, cannot be loaded.*/nonexistent/librender_image_oiio.so");
}

}  // namespace
}  // namespace render
