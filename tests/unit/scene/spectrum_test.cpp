// <spectrum> values: wavelength:value lists become linear sRGB as in Mitsuba 3's RGB variants
// (CIE 1931 integration, D65-weighted for everything but emission, Mitsuba's normalisations
// and XYZ-to-sRGB matrix), single values are grey except directly inside an emitter, and bad
// lists are located errors. The expected colours are known results, not our code's output:
// a flat reflectance is its grey, the D65 illuminant emitted is white, a flat emission is the
// sRGB colour of XYZ (1, 1, 1).

#include <gtest/gtest.h>

#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "core/base/error.h"
#include "core/image/spectrum.h"
#include "core/lights/light.h"
#include "core/materials/diffuse.h"
#include "core/scene/loader/scene_loader.h"

namespace render {
namespace {

::testing::AssertionResult near(const Rgb& a, const Rgb& b, double tolerance) {
    for (int c = 0; c < 3; ++c)
        if (!(std::abs(a[c] - b[c]) <= tolerance))
            return ::testing::AssertionFailure() << a << " vs " << b << " (channel " << c << ")";
    return ::testing::AssertionSuccess();
}

// The CIE D65 illuminant at 10 nm, 360 to 830 nm (relative, 100 at 560 nm), as published.
const std::vector<double> kD65Wavelengths = [] {
    std::vector<double> w;
    for (int l = 360; l <= 830; l += 10) w.push_back(l);
    return w;
}();
const std::vector<double> kD65 = {
    46.6383, 52.0891, 49.9755, 54.6482, 82.7549, 91.486,  93.4318, 86.6823, 104.865, 117.008,
    117.812, 114.861, 115.923, 108.811, 109.354, 107.802, 104.79,  107.689, 104.405, 104.046,
    100.0,   96.3342, 95.788,  88.6856, 90.0062, 89.5991, 87.6987, 83.2886, 83.6992, 80.0268,
    80.2146, 82.2778, 78.2842, 69.7213, 71.6091, 74.349,  61.604,  69.8856, 75.087,  63.5927,
    46.4182, 66.8054, 63.3828, 64.304,  59.4519, 51.959,  57.4406, 60.3125};

// sRGB of XYZ (1, 1, 1), the equal-energy white, from the Rec. 709 matrix.
const Rgb kEqualEnergyWhite(1.204794f, 0.948291f, 0.908916f);

TEST(Spectrum, FlatReflectanceIsItsGrey) {
    // Weighted by D65 and normalised so that D65 has luminance 1: a flat spectrum is grey. The
    // 5 nm tables and Mitsuba's matrix agree with the sRGB white to about 1e-3.
    for (double v : {0.1, 0.5, 1.0}) {
        const SpectrumToRgb s = spectrum_to_linear_srgb({360, 830}, {v, v}, true, true);
        EXPECT_TRUE(near(s.rgb, Rgb(float(v)), 1.5e-3 * v)) << v;
        EXPECT_FALSE(s.clamped);
    }
}

TEST(Spectrum, EmittedD65IsWhiteAndFlatEmissionIsEqualEnergyWhite) {
    // Emission is integrated without an illuminant: D65 itself, scaled to luminance 1, is the
    // sRGB white (1, 1, 1); a flat spectrum is XYZ (1, 1, 1), pinkish in sRGB.
    std::vector<double> d65 = kD65;
    for (double& v : d65) v /= 98.99741751876255;
    EXPECT_TRUE(
        near(spectrum_to_linear_srgb(kD65Wavelengths, d65, false, false).rgb, Rgb(1.0f), 1.5e-3));
    EXPECT_TRUE(near(spectrum_to_linear_srgb({360, 830}, {2, 2}, false, false).rgb,
                     kEqualEnergyWhite * 2.0f, 2e-3));
    EXPECT_TRUE(near(xyz_to_linear_srgb(1, 1, 1), kEqualEnergyWhite, 1e-6));
}

TEST(Spectrum, OnlyTheGivenRangeCountsAndColoursAreClamped) {
    // Mitsuba integrates only between the first and last wavelength (zero outside).
    const SpectrumToRgb visible = spectrum_to_linear_srgb({400, 700}, {1, 1}, true, true);
    EXPECT_LT(visible.rgb.g, 1.0f);
    EXPECT_GT(visible.rgb.g, 0.99f);
    // A long-pass red reflectance is outside the sRGB gamut: green and blue clamp to 0.
    const SpectrumToRgb red =
        spectrum_to_linear_srgb({360, 595, 605, 830}, {0, 0, 1, 1}, true, true);
    EXPECT_TRUE(red.clamped);
    EXPECT_GT(red.rgb.r, 0.8f);
    EXPECT_EQ(red.rgb.g, 0.0f);
    EXPECT_EQ(red.rgb.b, 0.0f);
    // Bounded colours stop at 1; unbounded ones (emission, IORs) only at 0.
    EXPECT_EQ(spectrum_to_linear_srgb({360, 830}, {3, 3}, true, true).rgb, Rgb(1.0f));
    EXPECT_GT(spectrum_to_linear_srgb({360, 830}, {3, 3}, true, false).rgb.g, 2.9f);
    // Linear in the values.
    const Rgb a = spectrum_to_linear_srgb({400, 500, 650}, {0.2, 0.6, 0.3}, true, true).rgb;
    const Rgb b = spectrum_to_linear_srgb({400, 500, 650}, {0.1, 0.3, 0.15}, true, true).rgb;
    EXPECT_TRUE(near(a, b * 2.0f, 1e-6));
}

// --- in scene files --------------------------------------------------------------------------

std::unique_ptr<Scene> scene_with(const std::string& body) {
    return load_scene_from_string(
        "<scene version=\"3.0.0\">\n<sensor type=\"perspective\"><float name=\"fov\" "
        "value=\"45\"/></sensor>\n" +
            body + "\n</scene>",
        ".");
}

Rgb reflectance_of(const std::string& spectrum) {
    auto scene = scene_with("<shape type=\"rectangle\"><bsdf type=\"diffuse\">" + spectrum +
                            "</bsdf></shape>");
    const auto* d = dynamic_cast<const DiffuseBsdf*>(scene->shapes()[0]->bsdf);
    EXPECT_NE(d, nullptr);
    return d ? d->reflectance() : Rgb(-1.0f);
}

// A point light's intensity, relative to one of intensity 1 (power is proportional to it).
Rgb intensity_of(const std::string& spectrum) {
    auto power = [](const std::string& value) {
        auto scene = scene_with("<shape type=\"rectangle\"/><emitter type=\"point\">" + value +
                                "</emitter>");
        return scene->lights()[0]->power();
    };
    const Rgb unit = power("<rgb name=\"intensity\" value=\"1\"/>"), p = power(spectrum);
    return Rgb(p.r / unit.r, p.g / unit.g, p.b / unit.b);
}

TEST(SpectrumInScenes, ReflectancesAndEmittersFollowMitsubasRgbVariants) {
    EXPECT_EQ(reflectance_of("<spectrum name=\"reflectance\" value=\"0.3\"/>"), Rgb(0.3f));
    EXPECT_TRUE(near(reflectance_of("<spectrum name=\"reflectance\" value=\"360:0.5, 830:0.5\"/>"),
                     Rgb(0.5f), 1e-3));
    EXPECT_TRUE(near(reflectance_of("<spectrum name=\"reflectance\" "
                                    "value=\"360:0.2 500:0.2, 600:0.2  830:0.2\"/>"),
                     Rgb(0.2f), 1e-3));
    // Directly inside an emitter a single value is that multiple of the equal-energy white,
    // and a list is integrated without D65.
    EXPECT_TRUE(near(intensity_of("<spectrum name=\"intensity\" value=\"5\"/>"),
                     kEqualEnergyWhite * 5.0f, 1e-5));
    EXPECT_TRUE(near(intensity_of("<spectrum name=\"intensity\" value=\"360:5, 830:5\"/>"),
                     kEqualEnergyWhite * 5.0f, 1e-2));
}

std::string load_error(const std::string& body) {
    try {
        scene_with(body);
    } catch (const SceneError& e) {
        return e.what();
    }
    ADD_FAILURE() << "no error for " << body;
    return "";
}

TEST(SpectrumInScenes, BadListsAreLocatedErrors) {
    const std::string bsdf = "<bsdf type=\"diffuse\">\n";
    auto error = [&](const std::string& value) {
        return load_error(bsdf + "<spectrum name=\"reflectance\" value=\"" + value + "\"/></bsdf>");
    };
    EXPECT_EQ(error("500:0.5"),
              "<string>:4: spectrum \"reflectance\": a wavelength:value spectrum "
              "needs at least two pairs");
    EXPECT_EQ(error("500:0.5, 400:0.2"),
              "<string>:4: spectrum \"reflectance\": wavelengths must "
              "increase (400.000000 after 500.000000)");
    EXPECT_EQ(error("400:0.1, 500-0.5"),
              "<string>:4: spectrum \"reflectance\": \"500-0.5\" is not a wavelength:value pair "
              "(a spectrum is one number or pairs \"400:0.1, 700:0.5\")");
    EXPECT_NE(error("400:0.1, 500:x").find("<string>:4: spectrum \"reflectance\" value"),
              std::string::npos);
    EXPECT_NE(error("0.1 0.2 0.3").find("use <rgb> for colours"), std::string::npos);
}

// --- spectrum files (.spd) -------------------------------------------------------------------

class SpectrumFileTest : public ::testing::Test {
  protected:
    void SetUp() override {
        dir_ = std::filesystem::temp_directory_path() /
               ("spectrum_file_test_" + std::to_string(::getpid()) + "_" +
                ::testing::UnitTest::GetInstance()->current_test_info()->name());
        std::filesystem::create_directories(dir_ / "scene");
    }
    void TearDown() override { std::filesystem::remove_all(dir_); }
    void write(const std::string& name, const std::string& text) {
        std::ofstream(dir_ / name, std::ios::binary) << text;
    }
    std::unique_ptr<Scene> load(const std::string& body) {
        write("scene/scene.xml",
              "<scene version=\"3.0.0\">\n<sensor type=\"perspective\"><float name=\"fov\" "
              "value=\"45\"/></sensor>\n" +
                  body + "\n</scene>");
        return load_scene(dir_ / "scene/scene.xml", {}, dir_ / "scene");
    }
    std::string error(const std::string& body) {
        try {
            load(body);
        } catch (const SceneError& e) {
            return e.what();
        }
        return "loaded";
    }
    std::filesystem::path dir_;
};

// A file gives exactly what the same pairs give in value="...": for a reflectance (D65
// weighted, clamped to [0, 1]) and for an emitter (unweighted).
TEST_F(SpectrumFileTest, FilesConvertAsWavelengthLists) {
    write("scene/green.spd",
          "# a greenish reflectance\n\n400 0.1\n500, 0.6   # comment\n\t600 0.3\n700 0.05\n");
    auto reflectance = [&](const std::string& spectrum) {
        auto scene = load("<shape type=\"rectangle\"><bsdf type=\"diffuse\">" + spectrum +
                          "</bsdf></shape>");
        return dynamic_cast<const DiffuseBsdf&>(*scene->shapes()[0]->bsdf).reflectance();
    };
    const Rgb from_file = reflectance("<spectrum name=\"reflectance\" filename=\"green.spd\"/>");
    EXPECT_EQ(from_file, reflectance("<spectrum name=\"reflectance\" "
                                     "value=\"400:0.1, 500:0.6, 600:0.3, 700:0.05\"/>"));
    EXPECT_GT(from_file.g, from_file.r);
    auto intensity = [&](const std::string& spectrum) {
        return load("<shape type=\"rectangle\"/><emitter type=\"point\">" + spectrum + "</emitter>")
            ->lights()[0]
            ->power();
    };
    EXPECT_EQ(intensity("<spectrum name=\"intensity\" filename=\"green.spd\"/>"),
              intensity("<spectrum name=\"intensity\" value=\"400:0.1, 500:0.6, 600:0.3, "
                        "700:0.05\"/>"));
}

TEST_F(SpectrumFileTest, BadFilesAreLocatedErrors) {
    const std::string bsdf = "<shape type=\"rectangle\"><bsdf type=\"diffuse\">\n";
    auto with = [&](const std::string& file) {
        return error(bsdf + "<spectrum name=\"reflectance\" filename=\"" + file +
                     "\"/></bsdf></shape>");
    };
    const std::string spd = (dir_ / "scene/bad.spd").string();
    write("scene/bad.spd", "400 0.1\n# two numbers a line\n500 0.2 0.3\n");
    EXPECT_EQ(with("bad.spd"), spd +
                                   ":3: spectrum \"reflectance\": a line of a spectrum file is "
                                   "\"wavelength value\", got 3 numbers");
    write("scene/bad.spd", "500 0.1\n400 0.2\n");
    EXPECT_NE(with("bad.spd").find(spd + ":2: spectrum \"reflectance\": wavelengths must increase"),
              std::string::npos);
    write("scene/bad.spd", "500 0.1\n600 x\n");
    EXPECT_NE(with("bad.spd").find(spd + ":2:"), std::string::npos) << with("bad.spd");
    write("scene/bad.spd", "# only one\n500 0.1\n");
    EXPECT_NE(with("bad.spd").find("scene.xml:4: spectrum \"reflectance\": the spectrum file"),
              std::string::npos)
        << with("bad.spd");
    EXPECT_NE(with("missing.spd").find("scene.xml:4: <spectrum>: file not found"),
              std::string::npos)
        << with("missing.spd");
    // Confined to the scene's folder, as every file a job reads.
    write("outside.spd", "400 0.1\n500 0.2\n");
    EXPECT_NE(with("../outside.spd").find("is outside"), std::string::npos)
        << with("../outside.spd");
}

}  // namespace
}  // namespace render
