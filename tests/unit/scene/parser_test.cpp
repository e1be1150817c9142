// The Mitsuba 3 XML scene loader: a scene using every supported tag round-trips; every kind of
// malformed input gives a SceneError naming file:line and the field (and nothing crashes);
// old-version files are upgraded; every shipped scene loads.

#include <gtest/gtest.h>

#include <unistd.h>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>

#include "core/base/error.h"
#include "core/lights/area_light.h"
#include "core/media/medium.h"
#include "core/scene/loader/scene_loader.h"
#include "core/scene/loader/version_upgrade.h"
#include "core/shapes/sphere.h"
#include "core/shapes/triangle_mesh.h"

namespace render {
namespace {

namespace fs = std::filesystem;

constexpr float kDeg = 3.14159265358979f / 180.0f;

class ParserTest : public ::testing::Test {
  protected:
    void SetUp() override {
        dir_ = fs::temp_directory_path() /
               ("parser_test_" + std::to_string(::getpid()) + "_" +
                ::testing::UnitTest::GetInstance()->current_test_info()->name());
        fs::create_directories(dir_);
        write("tri.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//1 3//1\n");
        write("quad.ply",
              "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
              "property float z\nelement face 1\nproperty list uchar int vertex_indices\n"
              "end_header\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3\n");
    }
    void TearDown() override { fs::remove_all(dir_); }

    fs::path write(const std::string& name, const std::string& text) {
        fs::path p = dir_ / name;
        std::ofstream(p, std::ios::binary) << text;
        return p;
    }

    std::unique_ptr<Scene> load(const std::string& xml,
                                const std::map<std::string, std::string>& defines = {}) {
        return load_scene_from_string(xml, dir_, defines);
    }

    // The error message of loading `xml`; fails the test if it loads.
    std::string error(const std::string& xml,
                      const std::map<std::string, std::string>& defines = {}) {
        try {
            load(xml, defines);
        } catch (const SceneError& e) {
            return e.what();
        }
        ADD_FAILURE() << "no error for:\n" << xml;
        return "";
    }

    fs::path dir_;
};

// A scene whose body is `body`, with a minimal camera unless the body has its own.
std::string with_camera(const std::string& body) {
    return "<scene version=\"3.0.0\">\n"
           "<sensor type=\"perspective\"><float name=\"fov\" value=\"45\"/></sensor>\n" +
           body + "</scene>\n";
}

#define EXPECT_CONTAINS(haystack, needle) \
    EXPECT_NE(std::string(haystack).find(needle), std::string::npos) << (haystack)

const std::string kEveryTag = R"(<scene version="3.0.0">
    <default name="spp" value="8"/>
    <default name="radius" value="0.5"/>
    <include filename="included.xml"/>
    <integrator type="pt">
        <integer name="max_depth" value="12"/>
        <integer name="rr_depth" value="3"/>
    </integrator>
    <sensor type="perspective">
        <float name="fov" value="40"/>
        <string name="fov_axis" value="x"/>
        <float name="near_clip" value="0.1"/>
        <float name="far_clip" value="100"/>
        <transform name="to_world">
            <lookat origin="0, 0, 5" target="0, 0, 0" up="0, 1, 0"/>
            <translate x="1"/>
        </transform>
        <sampler type="independent">
            <integer name="sample_count" value="$spp"/>
        </sampler>
        <film type="hdrfilm">
            <integer name="width" value="320"/>
            <integer name="height" value="240"/>
            <string name="file_format" value="openexr"/>
            <string name="pixel_format" value="rgb"/>
            <string name="component_format" value="float32"/>
            <rfilter type="gaussian"><float name="stddev" value="0.5"/></rfilter>
        </film>
    </sensor>
    <bsdf type="diffuse" id="white">
        <rgb name="reflectance" value="0.8 0.8 0.8"/>
    </bsdf>
    <bsdf type="twosided" id="two">
        <bsdf type="diffuse"><spectrum name="reflectance" value="0.5"/></bsdf>
    </bsdf>
    <bsdf type="twosided" id="two_ref"><ref id="white"/></bsdf>
    <shape type="sphere" id="ordered">
        <transform name="to_world">
            <translate value="1, 0, 0"/>
            <rotate z="1" angle="90"/>
            <scale value="2"/>
        </transform>
        <ref id="white"/>
    </shape>
    <shape type="sphere">
        <point name="center" x="0" y="0" z="-3"/>
        <float name="radius" value="$radius"/>
        <bsdf type="conductor"><string name="material" value="none"/></bsdf>
    </shape>
    <shape type="rectangle">
        <transform name="to_world">
            <matrix value="1 0 0 0  0 1 0 0  0 0 1 2  0 0 0 1"/>
            <scale x="0.5" y="0.5" z="1"/>
        </transform>
        <boolean name="flip_normals" value="true"/>
        <ref id="two"/>
        <emitter type="area"><rgb name="radiance" value="1, 2, 3"/></emitter>
    </shape>
    <shape type="cube"><ref id="two_ref"/></shape>
    <shape type="disk"/>
    <shape type="obj">
        <string name="filename" value="tri.obj"/>
        <boolean name="face_normals" value="true"/>
    </shape>
    <shape type="ply">
        <string name="filename" value="quad.ply"/>
    </shape>
    <emitter type="point">
        <point name="position" value="0, 3, 0"/>
        <rgb name="intensity" value="5"/>
    </emitter>
    <emitter type="directional">
        <vector name="direction" x="0" y="-1" z="0"/>
        <rgb name="irradiance" value="1"/>
    </emitter>
    <emitter type="constant"><rgb name="radiance" value="0.1"/></emitter>
</scene>
)";

std::string every_tag_scene() {
    return kEveryTag;
}

TEST_F(ParserTest, EveryTagRoundTrips) {
    write("included.xml",
          "<scene version=\"3.0.0\">\n"
          "  <shape type=\"sphere\" id=\"from_include\">\n"
          "    <point name=\"center\" x=\"5\" y=\"5\" z=\"5\"/>\n"
          "  </shape>\n"
          "</scene>\n");
    std::unique_ptr<Scene> scene = load(every_tag_scene());

    EXPECT_EQ(scene->settings.integrator, "pt");
    EXPECT_EQ(scene->settings.max_depth, 12);
    EXPECT_EQ(scene->settings.rr_depth, 3);
    EXPECT_EQ(scene->settings.sample_count, 8);
    EXPECT_EQ(scene->source_file, "<string>");

    const PerspectiveCamera& cam = scene->camera();
    EXPECT_EQ(cam.width(), 320);
    EXPECT_EQ(cam.height(), 240);
    // lookat, then translate by +x: the translation applies after the lookat.
    EXPECT_NEAR(cam.position().x, 1.0f, 1e-6f);
    EXPECT_NEAR(cam.position().y, 0.0f, 1e-6f);
    EXPECT_NEAR(cam.position().z, 5.0f, 1e-6f);
    EXPECT_NEAR(cam.forward().z, -1.0f, 1e-6f);
    float tan_x = std::tan(20 * kDeg), tan_y = tan_x * 240.0f / 320.0f;
    EXPECT_NEAR(cam.image_plane_area(), 4 * tan_x * tan_y, 1e-5f);

    // 1 included + 2 spheres + rectangle, cube, disk, obj, ply.
    ASSERT_EQ(scene->shapes().size(), 8u);
    EXPECT_EQ(scene->lights().size(), 4u);  // area, point, directional, constant
    EXPECT_EQ(scene->background_lights().size(), 1u);

    auto* included = dynamic_cast<const Sphere*>(scene->shapes()[0].get());
    ASSERT_NE(included, nullptr);
    EXPECT_EQ(included->center(), Vec3(5, 5, 5));
    EXPECT_EQ(included->radius(), 1.0f);  // default radius

    // translate(1,0,0), then rotate 90 degrees about z, then scale 2: each applies after the
    // previous, so the centre goes (0,0,0) -> (1,0,0) -> (0,1,0) -> (0,2,0).
    auto* ordered = dynamic_cast<const Sphere*>(scene->shapes()[1].get());
    ASSERT_NE(ordered, nullptr);
    EXPECT_NEAR(ordered->center().x, 0.0f, 1e-6f);
    EXPECT_NEAR(ordered->center().y, 2.0f, 1e-6f);
    EXPECT_NEAR(ordered->center().z, 0.0f, 1e-6f);
    EXPECT_NEAR(ordered->radius(), 2.0f, 1e-6f);

    auto* defaulted = dynamic_cast<const Sphere*>(scene->shapes()[2].get());
    ASSERT_NE(defaulted, nullptr);
    EXPECT_EQ(defaulted->radius(), 0.5f);  // from <default name="radius">
    EXPECT_EQ(defaulted->center(), Vec3(0, 0, -3));

    // matrix (translate z by 2), then scale: the rectangle spans [-0.5,0.5]^2 at z = 1.
    const Shape* rect = scene->shapes()[3].get();
    Aabb b = rect->bounds();
    EXPECT_NEAR(b.lo.x, -0.5f, 1e-6f);
    EXPECT_NEAR(b.hi.y, 0.5f, 1e-6f);
    EXPECT_NEAR(b.lo.z, 2.0f, 1e-6f);  // scale z = 1 keeps the translation's z = 2
    EXPECT_NE(rect->emitter, nullptr);
    EXPECT_NEAR(rect->surface_area(), 1.0f, 1e-6f);

    // Every shape has a BSDF (the obj and ply got the default diffuse).
    for (const auto& shape : scene->shapes()) EXPECT_NE(shape->bsdf, nullptr);
    EXPECT_EQ(scene->shapes()[6]->bsdf, scene->shapes()[7]->bsdf);  // one default instance
    EXPECT_NE(scene->shapes()[1]->bsdf, scene->shapes()[2]->bsdf);
}

TEST_F(ParserTest, DefinesOverrideDefaults) {
    write("included.xml", "<scene version=\"3.0.0\"/>");
    EXPECT_EQ(load(every_tag_scene(), {{"spp", "32"}})->settings.sample_count, 32);
    auto scene = load(every_tag_scene(), {{"radius", "0.25"}});
    EXPECT_EQ(dynamic_cast<const Sphere*>(scene->shapes()[1].get())->radius(), 0.25f);
    // A define that no default declares is still usable.
    std::string xml = with_camera(
        "<integrator type=\"$algo\"><integer name=\"max_depth\" value=\"$depth\"/></integrator>");
    auto s2 = load(xml, {{"algo", "eyelight"}, {"depth", "4"}});
    EXPECT_EQ(s2->settings.integrator, "eyelight");
    EXPECT_EQ(s2->settings.max_depth, 4);
}

TEST_F(ParserTest, CameraFovAxisAndDefaults) {
    auto scene = load(
        "<scene version=\"3.0.0\"><sensor type=\"perspective\"><float name=\"fov\" "
        "value=\"30\"/><string name=\"fov_axis\" value=\"y\"/></sensor></scene>");
    EXPECT_EQ(scene->camera().width(), 768);  // Mitsuba's hdrfilm default
    EXPECT_EQ(scene->camera().height(), 576);
    float tan_y = std::tan(15 * kDeg), tan_x = tan_y * 768.0f / 576.0f;
    EXPECT_NEAR(scene->camera().image_plane_area(), 4 * tan_x * tan_y, 1e-5f);
    EXPECT_EQ(scene->settings.max_depth, -1);
    EXPECT_EQ(scene->settings.integrator, "path");
}

TEST_F(ParserTest, Version06IsUpgraded) {
    EXPECT_EQ(to_snake_case("diffuseReflectance"), "diffuse_reflectance");
    EXPECT_EQ(to_snake_case("intIOR"), "int_ior");
    EXPECT_EQ(to_snake_case("toWorld"), "to_world");
    EXPECT_EQ(to_snake_case("max_depth"), "max_depth");
    auto scene = load(R"(<scene version="0.6.0">
        <integrator type="path">
            <integer name="maxDepth" value="7"/>
            <integer name="rrDepth" value="2"/>
        </integrator>
        <sensor type="perspective">
            <float name="fov" value="30"/>
            <string name="fovAxis" value="y"/>
            <transform name="toWorld">
                <lookAt origin="0, 0, 5" target="0, 0, 0" up="0, 1, 0"/>
            </transform>
            <sampler type="independent"><integer name="sampleCount" value="4"/></sampler>
            <film type="hdrfilm">
                <integer name="width" value="64"/><integer name="height" value="48"/>
                <rfilter type="box"/>
            </film>
        </sensor>
        <bsdf type="diffuse" id="d"><rgb name="diffuseReflectance" value="0.5"/></bsdf>
        <bsdf type="dielectric" id="g">
            <float name="intIOR" value="1.5"/><float name="extIOR" value="1"/>
        </bsdf>
        <bsdf type="phong" id="p">
            <spectrum name="diffuseReflectance" value="0.1"/>
            <spectrum name="specularReflectance" value="0.7"/>
            <float name="exponent" value="90"/>
        </bsdf>
        <shape type="sphere"><float name="radius" value="1"/><ref id="d"/></shape>
        <shape type="rectangle"><boolean name="flipNormals" value="true"/><ref id="g"/></shape>
        <shape type="obj">
            <string name="filename" value="tri.obj"/>
            <boolean name="faceNormals" value="true"/>
            <ref id="p"/>
        </shape>
    </scene>)");
    EXPECT_EQ(scene->settings.max_depth, 7);
    EXPECT_EQ(scene->settings.rr_depth, 2);
    EXPECT_EQ(scene->settings.sample_count, 4);
    EXPECT_EQ(scene->shapes().size(), 3u);
    EXPECT_NEAR(scene->camera().position().z, 5.0f, 1e-6f);
    // Version 3 files are not upgraded: camelCase names are unused parameters there.
    std::string e = error(with_camera(
        "<bsdf type=\"diffuse\"><rgb name=\"diffuseReflectance\" value=\"0.5\"/></bsdf>"));
    EXPECT_CONTAINS(e, "<string>:3:");
    EXPECT_CONTAINS(e, "diffuseReflectance");
}

TEST_F(ParserTest, IncludeErrors) {
    std::string e = error(with_camera("<include filename=\"nowhere.xml\"/>\n"));
    EXPECT_CONTAINS(e, "<string>:3: <include>: file not found: ");
    EXPECT_CONTAINS(e, "nowhere.xml");

    write("a.xml", "<scene version=\"3.0.0\">\n<include filename=\"b.xml\"/>\n</scene>\n");
    write("b.xml", "<scene version=\"3.0.0\">\n\n<include filename=\"a.xml\"/>\n</scene>\n");
    e = error(with_camera("<include filename=\"a.xml\"/>\n"));
    EXPECT_CONTAINS(e, "b.xml:3: <include>: include cycle");

    write("bad.xml", "<scene version=\"3.0.0\">\n<shape type=\"sphere\">\n</scene>\n");
    e = error(with_camera("<include filename=\"bad.xml\"/>\n"));
    EXPECT_CONTAINS(e, "bad.xml:3: malformed XML");
    EXPECT_CONTAINS(e, "included from <string>:3");
}

TEST_F(ParserTest, MalformedInputsNameFileLineAndField) {
    struct Case {
        std::string body;      // after the camera line (line 2): body starts at line 3
        std::string expected;  // substrings, separated by '|'
    };
    const Case cases[] = {
        // bad XML
        {"<shape type=\"sphere\">\n</scene>", "<string>:4: malformed XML|mismatch"},
        // unknown tag
        {"<foo/>", "<string>:3: unknown tag <foo> in <scene>"},
        {"<shape type=\"sphere\"><colour name=\"x\"/></shape>", "<string>:3: unknown tag <colour>"},
        // unknown attribute
        {"<shape type=\"sphere\" colour=\"red\"/>",
         "<string>:3: unknown attribute \"colour\" on <shape type=\"sphere\">"},
        {"<shape type=\"sphere\"><float name=\"radius\" value=\"1\" unit=\"m\"/></shape>",
         "<string>:3: unknown attribute \"unit\""},
        // geometry our floats and Embree cannot handle (a scale of -1e30 aborted the process
        // in Embree's ray validity assertion)
        {"<shape type=\"rectangle\"><transform name=\"to_world\"><scale value=\"-1e30\"/>"
         "</transform></shape>",
         "<string>:3: <shape type=\"rectangle\">: its geometry reaches beyond 1e12"},
        {"<shape type=\"sphere\"><float name=\"radius\" value=\"1e13\"/></shape>",
         "<string>:3:|beyond 1e12"},
        // unknown plugin types
        {"<shape type=\"teapot\"/>", "<string>:3: unknown shape type \"teapot\""},
        {"<bsdf type=\"velvet\"/>", "<string>:3:|velvet"},
        {"<emitter type=\"projector\"/>", "<string>:3:|projector"},
        {"<integrator type=\"path\"/><integrator type=\"path\"/>", "only one <integrator>"},
        // unused parameter
        {"<shape type=\"sphere\">\n<float name=\"radiuss\" value=\"1\"/></shape>",
         "<string>:4: unused parameter \"radiuss\" in shape \"sphere\""},
        {"<integrator type=\"path\"><integer name=\"max_depth\" value=\"-2\"/></integrator>",
         "<string>:3: integrator \"path\", parameter \"max_depth\""},
        {"<bsdf type=\"diffuse\">\n<rgb name=\"reflectence\" value=\"1\"/></bsdf>",
         "<string>:4: unused parameter \"reflectence\""},
        // missing mesh
        {"<shape type=\"ply\"><string name=\"filename\" value=\"models/none.ply\"/></shape>",
         "<string>:3: shape \"ply\", parameter \"filename\": mesh file not found: |none.ply"},
        // NaN, inf and garbage numbers
        {"<shape type=\"sphere\"><float name=\"radius\" value=\"nan\"/></shape>",
         "<string>:3: float \"radius\": \"nan\" is not a finite number"},
        {"<shape type=\"sphere\"><point name=\"center\" value=\"0, inf, 0\"/></shape>",
         "<string>:3: point \"center\": \"inf\" is not a finite number"},
        {"<shape type=\"sphere\"><float name=\"radius\" value=\"1e40\"/></shape>",
         "float \"radius\": \"1e40\" is not a finite number"},
        {"<shape type=\"sphere\"><float name=\"radius\" value=\"1.5cm\"/></shape>",
         "float \"radius\": \"1.5cm\" is not a number"},
        {"<integrator type=\"path\"><integer name=\"max_depth\" value=\"3.5\"/></integrator>",
         "integer \"max_depth\": \"3.5\" is not an integer"},
        {"<shape type=\"obj\"><boolean name=\"face_normals\" value=\"yes\"/></shape>",
         "boolean \"face_normals\": \"yes\" is not a boolean"},
        {"<shape type=\"cube\"><transform name=\"to_world\"><matrix value=\"1 0 0\"/>"
         "</transform></shape>",
         "<matrix>: value needs 16 numbers"},
        {"<bsdf type=\"diffuse\"><rgb name=\"reflectance\" value=\"1, 2\"/></bsdf>",
         "rgb \"reflectance\": value needs 1 or 3 numbers"},
        {"<bsdf type=\"diffuse\"><spectrum name=\"reflectance\" value=\"400:0.1\"/></bsdf>",
         "spectrum \"reflectance\": a wavelength:value spectrum needs at least two pairs"},
        // negative radius, bad sphere transform
        {"<shape type=\"sphere\">\n<float name=\"radius\" value=\"-1\"/></shape>",
         "<string>:4: shape \"sphere\", parameter \"radius\": the radius must be positive"},
        {"<shape type=\"sphere\"><transform name=\"to_world\"><scale x=\"1\" y=\"2\"/>"
         "</transform></shape>",
         "parameter \"to_world\": a sphere's to_world must be a similarity"},
        // undefined $var
        {"<shape type=\"sphere\"><float name=\"radius\" value=\"$size\"/></shape>",
         "<string>:3: undefined parameter \"$size\""},
        // unknown ref id
        {"<shape type=\"sphere\"><ref id=\"nope\"/></shape>",
         "<string>:3: <ref>: unknown id \"nope\""},
        {"<bsdf type=\"diffuse\" id=\"a\"/><bsdf type=\"diffuse\" id=\"a\"/>",
         "duplicate id \"a\""},
        // Participating media (docs/design/media.md).
        {"<medium type=\"fog\"/>", "<string>:3: unknown medium type \"fog\"|homogeneous"},
        {"<medium type=\"homogeneous\"><float name=\"albedo\" value=\"1.5\"/></medium>",
         "<string>:3: medium \"homogeneous\", parameter \"albedo\": must be in [0, 1]"},
        {"<medium type=\"homogeneous\"><rgb name=\"sigma_t\" value=\"-1\"/></medium>",
         "<string>:3: medium \"homogeneous\", parameter \"sigma_t\": must be finite and >= 0"},
        {"<medium type=\"homogeneous\"><phase type=\"hg\"><float name=\"g\" value=\"1\"/>"
         "</phase></medium>",
         "<string>:3: phase \"hg\", parameter \"g\": must be in (-1, 1)"},
        {"<medium type=\"homogeneous\"><phase type=\"rayleigh\"/></medium>",
         "unknown phase function type \"rayleigh\""},
        {"<shape type=\"sphere\"><ref name=\"interior\" id=\"gas\"/></shape>",
         "<string>:3: <ref>: unknown medium \"gas\""},
        {"<bsdf type=\"diffuse\" id=\"d\"/><shape type=\"sphere\"><ref name=\"interior\" "
         "id=\"d\"/></shape>",
         "\"d\" is not a medium"},
        {"<medium type=\"homogeneous\" id=\"m\"/><shape type=\"sphere\"><ref "
         "name=\"interior\" id=\"m\"/><ref name=\"interior\" id=\"m\"/></shape>",
         "interior medium is given twice"},
        // textures
        {"<bsdf type=\"diffuse\"><texture type=\"bitmap\" name=\"reflectance\"/></bsdf>",
         "<string>:3: texture \"bitmap\" needs parameter \"filename\""},
        // structure
        {"<shape type=\"sphere\"><bsdf type=\"diffuse\"/><bsdf type=\"diffuse\"/></shape>",
         "at most one bsdf"},
        {"<shape type=\"sphere\"><emitter type=\"point\"/></shape>", "must be of type \"area\""},
        {"<emitter type=\"area\"/>", "must be nested in a <shape>"},
        {"<float name=\"x\" value=\"1\"/>", "directly inside <scene>"},
        {"<shape type=\"sphere\">hello</shape>", "unexpected text inside"},
        {"<shape/>", "<string>:3: <shape> needs a \"type\" attribute"},
        {"<shape type=\"sphere\"><float name=\"radius\" value=\"1\"/>"
         "<float name=\"radius\" value=\"2\"/></shape>",
         "parameter \"radius\" of shape \"sphere\" is given twice"},
    };
    for (const Case& c : cases) {
        std::string e = error(with_camera(c.body + "\n"));
        size_t start = 0;
        while (start <= c.expected.size()) {
            size_t bar = c.expected.find('|', start);
            if (bar == std::string::npos) bar = c.expected.size();
            EXPECT_CONTAINS(e, c.expected.substr(start, bar - start)) << "  for: " << c.body;
            start = bar + 1;
        }
    }
}

TEST_F(ParserTest, SensorAndRootErrors) {
    EXPECT_CONTAINS(error("<scene version=\"3.0.0\"/>"), "no <sensor>");
    EXPECT_CONTAINS(error("<scene/>"), "needs a version attribute");
    EXPECT_CONTAINS(error("<scene version=\"three\"/>"), "not of the form major.minor.patch");
    EXPECT_CONTAINS(error("<world version=\"3.0.0\"/>"), "the root element must be <scene>");
    EXPECT_CONTAINS(error(""), "<string>:1: malformed XML: No document element found");
    EXPECT_CONTAINS(error("<scene version=\"3.0.0\"><sensor type=\"orthographic\"/></scene>"),
                    "unknown sensor type \"orthographic\"");
    // Mitsuba's thinlens requires its aperture.
    EXPECT_CONTAINS(error("<scene version=\"3.0.0\"><sensor type=\"thinlens\"/></scene>"),
                    "aperture_radius");
    EXPECT_CONTAINS(error("<scene version=\"3.0.0\"><sensor type=\"thinlens\">"
                          "<float name=\"aperture_radius\" value=\"0.1\"/>"
                          "<transform name=\"to_world\"><scale value=\"2\"/></transform>"
                          "</sensor></scene>"),
                    "may not scale");
    EXPECT_CONTAINS(error("<scene version=\"3.0.0\"><sensor type=\"perspective\">"
                          "<float name=\"fov\" value=\"40\"/>"
                          "<string name=\"focal_length\" value=\"35mm\"/></sensor></scene>"),
                    "give either \"fov\" or \"focal_length\"");
    EXPECT_CONTAINS(error("<scene version=\"3.0.0\">\n<sensor type=\"perspective\">"
                          "<float name=\"fov\" value=\"40\"/>"
                          "<string name=\"fov_axis\" value=\"diagonally\"/></sensor></scene>"),
                    "<string>:2: sensor \"perspective\", parameter \"fov_axis\"");
    EXPECT_CONTAINS(error(with_camera("<sensor type=\"perspective\"><float name=\"fov\" "
                                      "value=\"40\"/></sensor>")),
                    "only one <sensor>");
    EXPECT_CONTAINS(error("<scene version=\"3.0.0\"><sensor type=\"perspective\">"
                          "<float name=\"fov\" value=\"40\"/><film type=\"hdrfilm\">"
                          "<integer name=\"width\" value=\"0\"/></film></sensor></scene>"),
                    "parameter \"width\"");
    std::string deep = "<scene version=\"3.0.0\">";
    for (int i = 0; i < 200; ++i) deep += "<bsdf type=\"twosided\">";
    for (int i = 0; i < 200; ++i) deep += "</bsdf>";
    EXPECT_CONTAINS(error(deep + "</scene>"), "nested too deeply");
}

TEST_F(ParserTest, GarbageNeverCrashes) {
    write("included.xml", "<scene version=\"3.0.0\"/>");
    const std::string good = every_tag_scene();
    ASSERT_NO_THROW(load(good));
    std::mt19937 rng(12345);
    const std::string alphabet = "<>/=\" $#&;-+.,0123456789eE naxyz";
    int errors = 0;
    for (int i = 0; i < 300; ++i) {
        std::string s = good;
        int edits = 1 + int(rng() % 4);
        for (int k = 0; k < edits; ++k) {
            size_t at = rng() % s.size();
            switch (rng() % 3) {
                case 0:
                    s[at] = alphabet[rng() % alphabet.size()];
                    break;
                case 1:
                    s.erase(at, 1 + rng() % 8);
                    break;
                default:
                    s.insert(at, 1, alphabet[rng() % alphabet.size()]);
                    break;
            }
        }
        try {
            load(s);
        } catch (const SceneError&) {
            ++errors;
        }
        // Any other exception escapes and fails the test.
    }
    EXPECT_GT(errors, 100);
}

// ---------------------------------------------------------------------------------------
// Mitsuba 3 compatibility (docs/reference/scene-format.md, "Mitsuba 3 compatibility at a
// glance"): file resolution, <path>, wrapper integrators, the default lens, spot and
// thindielectric.

// The horizontal field of view (degrees) of a camera from its image-plane area and aspect.
float fov_x_of(const Scene& scene) {
    const float w = float(scene.camera().width()), h = float(scene.camera().height());
    const float tan_x = std::sqrt(scene.camera().image_plane_area() / 4.0f * w / h);
    return 2.0f * std::atan(tan_x) / kDeg;
}

TEST_F(ParserTest, IncludesResolveAgainstTheIncludingFileThenTheScene) {
    fs::create_directories(dir_ / "include");
    // include/a.xml names "include/b.xml" as Mitsuba users write it (from the scene's folder);
    // include/c.xml is named "c.xml", beside the including file.
    write("include/a.xml",
          "<scene version=\"3.0.0\">\n<include filename=\"include/b.xml\"/>\n"
          "<include filename=\"c.xml\"/>\n</scene>\n");
    write("include/b.xml",
          "<scene version=\"3.0.0\"><shape type=\"obj\"><string name=\"filename\" "
          "value=\"tri.obj\"/></shape></scene>");
    write("include/c.xml", "<scene version=\"3.0.0\"><shape type=\"sphere\"/></scene>");
    auto scene = load(with_camera("<include filename=\"include/a.xml\"/>\n"));
    EXPECT_EQ(scene->shapes().size(), 2u);
    // A file beside the including file wins over one of the same name in the scene's folder.
    write("include/tri.obj", "v 0 0 0\nv 2 0 0\nv 0 2 0\nf 1 2 3\n");
    auto beside = load(with_camera("<include filename=\"include/b.xml\"/>\n"));
    EXPECT_NEAR(beside->shapes()[0]->surface_area(), 2.0f, 1e-5f);
    // Not found anywhere: the message names the first place and the others.
    write("include/d.xml",
          "<scene version=\"3.0.0\">\n<include filename=\"missing.xml\"/>\n</scene>\n");
    std::string e = error(with_camera("<include filename=\"include/d.xml\"/>\n"));
    EXPECT_CONTAINS(
        e, "d.xml:2: <include>: file not found: " + (dir_ / "include/missing.xml").string());
    EXPECT_CONTAINS(e, "also looked for " + (dir_ / "missing.xml").string());
}

TEST_F(ParserTest, RelativeSceneFileResolvesFromTheWorkingDirectory) {
    // render include/scene.xml: the folders are relative to the working directory, and a mesh
    // named in an included file but found in the scene's folder must not be joined to the
    // included file's folder a second time.
    fs::create_directories(dir_ / "s/sub");
    write("s/scene.xml", with_camera("<include filename=\"sub/a.xml\"/>\n"));
    write("s/sub/a.xml",
          "<scene version=\"3.0.0\"><shape type=\"obj\"><string name=\"filename\" "
          "value=\"m.obj\"/></shape></scene>");
    write("s/m.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
    const fs::path cwd = fs::current_path();
    fs::current_path(dir_);
    std::unique_ptr<Scene> scene;
    EXPECT_NO_THROW(scene = load_scene("s/scene.xml"));
    fs::current_path(cwd);
    ASSERT_TRUE(scene);
    EXPECT_EQ(scene->shapes().size(), 1u);
}

TEST_F(ParserTest, ConfinedLoadRefusesFilesOutsideTheFolder) {
    // The server and the workers load a job's scene confined to the job's folder: nothing
    // outside it may be read.
    fs::create_directories(dir_ / "job/sub");
    write("outside.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
    write("outside.xml", "<scene version=\"3.0.0\"/>");
    write("job/inside.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
    write("job/sub/inner.xml",
          "<scene version=\"3.0.0\"><shape type=\"obj\"><string name=\"filename\" "
          "value=\"../inside.obj\"/></shape></scene>");
    auto scene_with = [&](const std::string& body) {
        return write("job/scene.xml", with_camera(body + "\n"));
    };
    auto confined_error = [&](const std::string& body) -> std::string {
        try {
            load_scene(scene_with(body), {}, dir_ / "job");
        } catch (const SceneError& e) {
            return e.what();
        }
        return "(no error)";
    };
    const std::string obj = "<shape type=\"obj\"><string name=\"filename\" value=\"$f\"/></shape>";
    // Inside: fine, also through "..", <path> and an include in a subfolder.
    EXPECT_NO_THROW(
        load_scene(scene_with("<include filename=\"sub/inner.xml\"/>"), {}, dir_ / "job"));
    EXPECT_NO_THROW(load_scene(scene_with("<path value=\"sub\"/>" + obj),
                               {{"f", "sub/../inside.obj"}}, dir_ / "job"));
    // Outside: refused, naming the line and the file; the same scenes load without the rule.
    EXPECT_CONTAINS(confined_error("<include filename=\"../outside.xml\"/>"),
                    "scene.xml:3: <include>: " + (dir_ / "outside.xml").string() + " is outside " +
                        (dir_ / "job").string());
    EXPECT_CONTAINS(confined_error("<shape type=\"obj\"><string name=\"filename\" value=\"" +
                                   (dir_ / "outside.obj").string() + "\"/></shape>"),
                    "parameter \"filename\": " + (dir_ / "outside.obj").string() + " is outside " +
                        (dir_ / "job").string());
    EXPECT_CONTAINS(confined_error("<path value=\"..\"/>"), "scene.xml:3: <path>: ");
    EXPECT_CONTAINS(confined_error("<path value=\"/\"/>"),
                    "is outside " + fs::weakly_canonical(dir_ / "job").string());
    EXPECT_NO_THROW(load_scene(scene_with("<include filename=\"../outside.xml\"/>")));
    // A symbolic link inside the folder that points outside is outside.
    std::error_code ec;
    fs::create_symlink(dir_ / "outside.obj", dir_ / "job/link.obj", ec);
    if (!ec) {
        EXPECT_CONTAINS(confined_error("<shape type=\"obj\"><string name=\"filename\" "
                                       "value=\"link.obj\"/></shape>"),
                        "is outside " + fs::weakly_canonical(dir_ / "job").string());
    }
}

TEST_F(ParserTest, SearchPathsAfterTheScenesFolder) {
    fs::create_directories(dir_ / "assets/more");
    write("assets/more/only_here.obj", "v 0 0 0\nv 3 0 0\nv 0 1 0\nf 1 2 3\n");
    write("assets/tri.obj", "v 0 0 0\nv 4 0 0\nv 0 1 0\nf 1 2 3\n");
    const std::string obj = "<shape type=\"obj\"><string name=\"filename\" value=\"$f\"/></shape>";
    // Without a <path> the file is not found, at its first candidate.
    EXPECT_CONTAINS(error(with_camera(obj), {{"f", "only_here.obj"}}),
                    "mesh file not found: " + (dir_ / "only_here.obj").string());
    // A relative <path> is relative to the scene's folder; <path>s are searched in order.
    auto scene = load(with_camera("<path value=\"assets/more\"/>\n<path value=\"" +
                                  (dir_ / "assets").string() + "\"/>\n" + obj),
                      {{"f", "only_here.obj"}});
    EXPECT_NEAR(scene->shapes()[0]->surface_area(), 1.5f, 1e-5f);
    // The scene's own folder comes before every <path>: tri.obj of the scene's folder.
    scene = load(with_camera("<path value=\"assets\"/>\n" + obj), {{"f", "tri.obj"}});
    EXPECT_NEAR(scene->shapes()[0]->surface_area(), 0.5f, 1e-5f);
    // A <path> applies from its position on.
    EXPECT_CONTAINS(
        error(with_camera(obj + "\n<path value=\"assets/more\"/>\n"), {{"f", "only_here.obj"}}),
        "mesh file not found");
    // A folder that does not exist is a warning, not an error; a malformed <path> is an error.
    ::testing::internal::CaptureStderr();
    load(with_camera("<path value=\"nowhere\"/>\n"));
    EXPECT_CONTAINS(::testing::internal::GetCapturedStderr(),
                    "<string>:3: <path>: folder not found: " + (dir_ / "nowhere").string());
    EXPECT_CONTAINS(error(with_camera("<path value=\"assets\" name=\"x\"/>")),
                    "<string>:3: unknown attribute \"name\"");
    EXPECT_CONTAINS(error(with_camera("<path/>")), "<string>:3:");
}

TEST_F(ParserTest, WrapperAndUnknownIntegratorsWarnInsteadOfFailing) {
    ::testing::internal::CaptureStderr();
    auto scene = load(with_camera(R"(<integrator type="moment">
    <integrator type="volpath">
        <integer name="max_depth" value="7"/>
        <integer name="rr_depth" value="3"/>
        <boolean name="hide_emitters" value="true"/>
    </integrator>
    <integrator type="path"/>
</integrator>
)"));
    std::string warnings = ::testing::internal::GetCapturedStderr();
    EXPECT_EQ(scene->settings.integrator, "volpath");
    EXPECT_EQ(scene->settings.max_depth, 7);
    EXPECT_EQ(scene->settings.rr_depth, 3);
    EXPECT_CONTAINS(warnings, "<string>:3: integrator \"moment\" wraps another");
    EXPECT_CONTAINS(warnings,
                    "<string>:7: integrator \"volpath\": parameter \"hide_emitters\" is "
                    "ignored");
    EXPECT_CONTAINS(warnings, "<string>:9: only the first integrator nested");

    // An integrator this renderer does not implement loads too (render --algo chooses).
    ::testing::internal::CaptureStderr();
    scene =
        load(with_camera("<integrator type=\"direct\">\n<integer name=\"emitter_samples\" "
                         "value=\"4\"/>\n<integer name=\"max_depth\" value=\"2\"/>\n"
                         "</integrator>\n"));
    warnings = ::testing::internal::GetCapturedStderr();
    EXPECT_EQ(scene->settings.integrator, "direct");
    EXPECT_EQ(scene->settings.max_depth, 2);
    EXPECT_CONTAINS(warnings, "<string>:4: integrator \"direct\": parameter \"emitter_samples\"");
    // What is read is still checked.
    EXPECT_CONTAINS(error(with_camera("<integrator type=\"aov\"><integrator type=\"path\">"
                                      "<integer name=\"rr_depth\" value=\"0\"/></integrator>"
                                      "</integrator>")),
                    "<string>:3: integrator \"path\", parameter \"rr_depth\": must be positive");
    EXPECT_CONTAINS(error(with_camera("<integrator type=\"moment\"><bsdf type=\"diffuse\"/>"
                                      "</integrator>")),
                    "unknown tag <bsdf>");
}

TEST_F(ParserTest, PerspectiveFocalLengthAndDiagonalFov) {
    auto camera = [&](const std::string& params, int w, int h) {
        return load("<scene version=\"3.0.0\"><sensor type=\"perspective\">" + params +
                    "<film type=\"hdrfilm\"><integer name=\"width\" value=\"" + std::to_string(w) +
                    "\"/><integer name=\"height\" value=\"" + std::to_string(h) +
                    "\"/></film></sensor></scene>");
    };
    // Mitsuba's default: a 50 mm lens on 36 x 24 mm film. On a 3:2 image the diagonal field
    // of view is the film's, so the horizontal one is that of 36 mm at 50 mm: 39.598 degrees.
    const float fov_50mm_x = 2.0f * std::atan(18.0f / 50.0f) / kDeg;
    EXPECT_NEAR(fov_x_of(*camera("", 360, 240)), fov_50mm_x, 1e-3f);
    EXPECT_NEAR(fov_x_of(*camera("<string name=\"focal_length\" value=\"50mm\"/>", 360, 240)),
                fov_50mm_x, 1e-3f);
    EXPECT_NEAR(fov_x_of(*camera("<string name=\"focal_length\" value=\"24\"/>", 36, 24)),
                2.0f * std::atan(18.0f / 24.0f) / kDeg, 1e-3f);
    EXPECT_NEAR(fov_x_of(*camera("<float name=\"focal_length\" value=\"100\"/>", 36, 24)),
                2.0f * std::atan(18.0f / 100.0f) / kDeg, 1e-3f);
    // A square image keeps the diagonal: tan(x/2) = tan(diag/2) / sqrt(2).
    const float tan_diag = std::sqrt(36.0f * 36.0f + 24.0f * 24.0f) / 100.0f;
    EXPECT_NEAR(fov_x_of(*camera("", 100, 100)),
                2.0f * std::atan(tan_diag / std::sqrt(2.0f)) / kDeg, 1e-3f);
    // fov_axis="diagonal" with an explicit fov.
    EXPECT_NEAR(fov_x_of(*camera("<float name=\"fov\" value=\"60\"/><string name=\"fov_axis\" "
                                 "value=\"diagonal\"/>",
                                 400, 300)),
                2.0f * std::atan(std::tan(30 * kDeg) * 0.8f) / kDeg, 1e-3f);
    // Errors name the field.
    EXPECT_CONTAINS(error("<scene version=\"3.0.0\">\n<sensor type=\"perspective\"><string "
                          "name=\"focal_length\" value=\"wide\"/></sensor></scene>"),
                    "<string>:2: sensor \"perspective\", parameter \"focal_length\"");
    EXPECT_CONTAINS(error("<scene version=\"3.0.0\"><sensor type=\"perspective\"><float "
                          "name=\"focal_length\" value=\"-5\"/></sensor></scene>"),
                    "parameter \"focal_length\"");
    // As in Mitsuba, fov_axis only goes with fov.
    EXPECT_CONTAINS(error("<scene version=\"3.0.0\"><sensor type=\"perspective\"><string "
                          "name=\"fov_axis\" value=\"y\"/></sensor></scene>"),
                    "unused parameter \"fov_axis\"");
}

// Constructs found in Mitsuba 3 scenes written by others (docs/reference/scene-format.md, "Mitsuba
// 3 scenes written by others"): Mitsuba's docs Cornell box references a named area emitter defined
// after the shapes; its material-preview scenes give a pinhole camera a focus_distance; Blender
// exports write zero principal point offsets.
TEST_F(ParserTest, NamedAreaEmitterReferencedBeforeItsDefinition) {
    auto scene = load(with_camera(R"(
        <shape type="rectangle"><ref id="lamp"/></shape>
        <shape type="rectangle"><ref id="lamp"/><bsdf type="diffuse"/></shape>
        <emitter type="area" id="lamp"><rgb name="radiance" value="1, 2, 3"/></emitter>
        <shape type="rectangle"><ref id="lamp"/></shape>
    )"));
    ASSERT_EQ(scene->shapes().size(), 3u);
    ASSERT_EQ(scene->lights().size(), 3u);  // one light per referencing shape
    for (const auto& shape : scene->shapes()) {
        ASSERT_NE(shape->emitter, nullptr);
        auto* area = dynamic_cast<const AreaLight*>(shape->emitter);
        ASSERT_NE(area, nullptr);
        EXPECT_EQ(area->shape(), shape.get());
        // Power = pi x area x radiance: the referenced radiance (1, 2, 3) on a 2 x 2 square.
        const Rgb power = area->power();
        EXPECT_NEAR(power.r, 3.14159265f * 4.0f * 1.0f, 1e-3f);
        EXPECT_NEAR(power.g, 3.14159265f * 4.0f * 2.0f, 1e-3f);
        EXPECT_NEAR(power.b, 3.14159265f * 4.0f * 3.0f, 1e-3f);
    }
    // Errors still name the line: an unknown id, a second emitter, a misspelt parameter, a
    // duplicate id, an anonymous area emitter outside a shape.
    EXPECT_CONTAINS(error(with_camera("<shape type=\"rectangle\"><ref id=\"lam\"/></shape>\n"
                                      "<emitter type=\"area\" id=\"lamp\"/>")),
                    "unknown id \"lam\"");
    EXPECT_CONTAINS(error(with_camera("<emitter type=\"area\" id=\"lamp\"/>\n<shape "
                                      "type=\"rectangle\"><ref id=\"lamp\"/><emitter "
                                      "type=\"area\"/></shape>")),
                    "at most one emitter");
    EXPECT_CONTAINS(error(with_camera(
                        "<shape type=\"rectangle\"><ref id=\"lamp\"/></shape>\n<emitter "
                        "type=\"area\" id=\"lamp\"><rgb name=\"radiant\" value=\"1\"/></emitter>")),
                    "<string>:4: unused parameter \"radiant\"");
    EXPECT_CONTAINS(error(with_camera("<emitter type=\"area\" id=\"lamp\"/>\n<emitter "
                                      "type=\"area\" id=\"lamp\"/>")),
                    "duplicate id \"lamp\"");
    EXPECT_CONTAINS(error(with_camera("<emitter type=\"area\"/>")),
                    "an area emitter must be nested in a <shape>");
}

TEST_F(ParserTest, PerspectiveFocusDistanceAndZeroPrincipalPointAreAccepted) {
    auto scene = load(
        "<scene version=\"3.0.0\"><sensor type=\"perspective\"><float name=\"fov\" "
        "value=\"45\"/><float name=\"focus_distance\" value=\"6\"/><float "
        "name=\"principal_point_offset_x\" value=\"0\"/><float "
        "name=\"principal_point_offset_y\" value=\"-0.0\"/></sensor></scene>");
    ASSERT_NE(scene, nullptr);
    EXPECT_NEAR(fov_x_of(*scene), 45.0f, 1e-3f);
    EXPECT_CONTAINS(error("<scene version=\"3.0.0\">\n<sensor type=\"perspective\"><float "
                          "name=\"principal_point_offset_y\" value=\"0.1\"/></sensor></scene>"),
                    "<string>:2: sensor \"perspective\", parameter \"principal_point_offset_y\"");
    EXPECT_CONTAINS(error("<scene version=\"3.0.0\"><sensor type=\"perspective\"><string "
                          "name=\"focus_distance\" value=\"near\"/></sensor></scene>"),
                    "focus_distance");
}

TEST(MitsubaCompatibility, TestSceneLoads) {
    // tests/data/mitsuba/README.md lists what each file exercises.
    const fs::path root = fs::path(RENDER_SOURCE_DIR) / "tests/data/mitsuba";
    ::testing::internal::CaptureStderr();
    std::unique_ptr<Scene> scene = load_scene(root / "scene.xml");
    ::testing::internal::GetCapturedStderr();
    EXPECT_EQ(scene->settings.integrator, "volpath");
    EXPECT_EQ(scene->settings.max_depth, 6);
    EXPECT_EQ(scene->shapes().size(), 3u);
    ASSERT_EQ(scene->lights().size(), 1u);
    EXPECT_NE(scene->lights()[0]->to_string().find("SpotLight"), std::string::npos);
    EXPECT_NEAR(fov_x_of(*scene), 2.0f * std::atan(18.0f / 50.0f) / kDeg, 1e-3f);
    // include/b.xml's pane comes first (its include precedes the other shapes).
    ASSERT_NE(scene->shapes()[0]->bsdf, nullptr);
    EXPECT_EQ(scene->shapes()[0]->bsdf->to_string().rfind("thindielectric(eta 1.49", 0), 0u)
        << scene->shapes()[0]->bsdf->to_string();
}

// Every scene file shipped in scenes/ (files under include/ folders are fragments that the
// scenes include).
std::vector<fs::path> shipped_scenes() {
    std::vector<fs::path> out;
    for (const auto& entry :
         fs::recursive_directory_iterator(fs::path(RENDER_SOURCE_DIR) / "scenes")) {
        if (entry.path().extension() != ".xml") continue;
        if (entry.path().string().find("/include/") != std::string::npos) continue;
        out.push_back(entry.path());
    }
    std::sort(out.begin(), out.end());
    return out;
}

TEST(ShippedScenes, AllLoad) {
    std::vector<fs::path> scenes = shipped_scenes();
    EXPECT_GE(scenes.size(), 7u);
    for (const fs::path& p : scenes) {
        SCOPED_TRACE(p.string());
        std::unique_ptr<Scene> scene;
        try {
            scene = load_scene(p);
        } catch (const SceneError& e) {
            ADD_FAILURE() << e.what();
            continue;
        }
        EXPECT_FALSE(scene->shapes().empty());
        // Some light: emitters, or a medium that emits (scenes/tests/flame.xml).
        bool emissive_medium = false;
        for (const auto& m : scene->media()) emissive_medium = emissive_medium || m->is_emissive();
        EXPECT_TRUE(!scene->lights().empty() || emissive_medium);
        EXPECT_EQ(scene->source_file, p.string());
    }
}

TEST(ShippedScenes, BitterliSettings) {
    fs::path root = fs::path(RENDER_SOURCE_DIR) / "scenes/bitterli";
    auto cornell = load_scene(root / "cornell-box/scene_v3.xml");
    EXPECT_EQ(cornell->settings.max_depth, 65);
    EXPECT_EQ(cornell->settings.sample_count, 64);
    EXPECT_EQ(cornell->camera().width(), 1024);
    EXPECT_NEAR(cornell->camera().position().z, 6.8f, 1e-6f);
    EXPECT_EQ(cornell->shapes().size(), 8u);
    EXPECT_EQ(cornell->lights().size(), 1u);
    auto mis = load_scene(root / "veach-mis/scene_v3.xml", {{"spp", "4"}, {"resx", "128"}});
    EXPECT_EQ(mis->settings.sample_count, 4);
    EXPECT_EQ(mis->camera().width(), 128);
    EXPECT_EQ(mis->camera().height(), 720);
    EXPECT_EQ(mis->lights().size(), 3u);
    auto bidir = load_scene(root / "veach-bidir/scene_v3.xml");
    EXPECT_EQ(bidir->settings.max_depth, 7);
    EXPECT_EQ(bidir->shapes().size(), 14u);
    EXPECT_EQ(bidir->lights().size(), 2u);
}

// The SmallVCM boxes: exact wall coordinates, inward normals, green wall on the left.
TEST(ShippedScenes, SmallVcmCornellGeometry) {
    fs::path root = fs::path(RENDER_SOURCE_DIR) / "scenes/smallvcm";
    struct Expected {
        const char* file;
        size_t shapes;
    };
    for (Expected ex : {Expected{"0-gbs_s.xml", 9}, Expected{"1-glm_c.xml", 8},
                        Expected{"2-gbs_p.xml", 7}, Expected{"3-gbs_b.xml", 9}}) {
        SCOPED_TRACE(ex.file);
        auto scene = load_scene(root / ex.file);
        EXPECT_EQ(scene->shapes().size(), ex.shapes);
        EXPECT_EQ(scene->lights().size(), 1u);
        EXPECT_EQ(scene->settings.max_depth, 10);
        EXPECT_EQ(scene->camera().width(), 512);
        EXPECT_EQ(scene->camera().height(), 512);
        EXPECT_NEAR(scene->camera().image_plane_area(), 4 * std::pow(std::tan(22.5f * kDeg), 2.0f),
                    1e-5f);
        Vec3 p = scene->camera().position();
        EXPECT_EQ(p, Vec3(-0.0439815f, -4.12529f, 0.222539f));
        Vec3 f = scene->camera().forward();
        Vec3 want = normalize(Vec3(0.00688625f, 0.998505f, -0.0542161f));
        EXPECT_NEAR(dot(f, want), 1.0f, 1e-6f);

        // The box bounds are exactly the document's numbers (all shapes lie inside).
        Aabb box;
        for (const auto& s : scene->shapes()) box.expand(s->bounds());
        EXPECT_EQ(box.lo, Vec3(-1.27029f, -1.25549f, -1.28002f));
        EXPECT_EQ(box.hi, Vec3(1.28975f, 1.30455f, 1.28002f));

        // Rays from inside the box hit every wall from its front side.
        const Vec3 inside(0.0f, 0.9f, 0.5f);
        const Vec3 dirs[] = {{0, 0, -1}, {0, 1, 0}, {-1, 0, 0}, {1, 0, 0}};
        for (const Vec3& d : dirs) {
            SurfaceInteraction si;
            ASSERT_TRUE(scene->intersect(Ray(inside, d), si));
            EXPECT_LT(dot(si.geometric_normal, d), -0.999f) << d;
        }
        // The left image edge shows the green wall (x = -1.27029).
        SurfaceInteraction si;
        Ray left = scene->camera().generate_ray(Vec2(1.0f, 256.0f));
        ASSERT_TRUE(scene->intersect(left, si));
        EXPECT_NEAR(si.p.x, -1.27029f, 1e-4f);
        Ray right = scene->camera().generate_ray(Vec2(511.0f, 256.0f));
        ASSERT_TRUE(scene->intersect(right, si));
        EXPECT_NEAR(si.p.x, 1.28975f, 1e-4f);
    }
}

// Fuzzing finding (tests/fuzz/corpus/mitsuba_xml/finding-*): a camera or a point or spot light
// placed beyond the scene's limits (1e12) loaded, and the first ray from it aborted Embree
// (`ray.valid()`) in the worker. Refused at their line instead; 1e12 itself is accepted.
TEST_F(ParserTest, CameraAndLightsBeyondTheSceneLimitsAreRefused) {
    const std::string film =
        "<film type=\"hdrfilm\"><integer name=\"width\" value=\"8\"/>"
        "<integer name=\"height\" value=\"8\"/></film>";
    auto sensor_at = [&](const std::string& x) {
        return "<scene version=\"3.0.0\"><sensor type=\"perspective\">"
               "<transform name=\"to_world\"><translate x=\"" +
               x + "\"/></transform>" + film + "</sensor><shape type=\"sphere\"/></scene>";
    };
    EXPECT_CONTAINS(error(sensor_at("3e38")), "places the camera beyond 1e12");
    EXPECT_CONTAINS(error(sensor_at("-2e12")), "to_world");
    EXPECT_NE(load(sensor_at("1e12")), nullptr);

    const std::string point = with_camera(
        "<shape type=\"sphere\"/><emitter type=\"point\">"
        "<point name=\"position\" value=\"3e38, 0, 0\"/></emitter>\n");
    EXPECT_CONTAINS(error(point), "parameter \"position\"");
    EXPECT_CONTAINS(error(point), "within 1e12 of the origin");
    EXPECT_CONTAINS(error(with_camera("<emitter type=\"spot\"><transform name=\"to_world\">"
                                      "<translate y=\"1e20\"/></transform></emitter>\n")),
                    "within 1e12 of the origin");
}

}  // namespace
}  // namespace render
