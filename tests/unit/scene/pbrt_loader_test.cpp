// The pbrt-v4 scene loader (core/scene/pbrt/): the tokenizer's edge cases, parameter lists, each
// transform directive against a matrix computed here, the camera's orientation and field of
// view, each shape's area and bounds, what each material and light becomes, Include/Import,
// and errors that name file:line and the directive or parameter.

#include <gtest/gtest.h>

#include <unistd.h>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>

#include "core/base/error.h"
#include "core/image/exr_io.h"
#include "core/media/medium.h"
#include "core/scene/loader/scene_loader.h"
#include "core/scene/pbrt/builders.h"
#include "core/scene/pbrt/parameters.h"
#include "core/scene/pbrt/scene_loader.h"
#include "core/scene/pbrt/tokenizer.h"
#include "core/scene/pbrt/transforms.h"
#include "core/shapes/bilinear_patch.h"
#include "core/shapes/triangle_mesh.h"

namespace render {
namespace {

namespace fs = std::filesystem;

constexpr double kPi = 3.14159265358979323846;

// A camera and film before WorldBegin, shared by the small scenes below.
const std::string kHeader =
    "LookAt 0 0 -5  0 0 0  0 1 0\nCamera \"perspective\" \"float fov\" 45\n"
    "Film \"rgb\" \"integer xresolution\" 8 \"integer yresolution\" 8\nWorldBegin\n";

class PbrtTest : public ::testing::Test {
  protected:
    void SetUp() override {
        dir_ = fs::temp_directory_path() /
               ("pbrt_test_" + std::to_string(::getpid()) + "_" +
                ::testing::UnitTest::GetInstance()->current_test_info()->name());
        fs::create_directories(dir_);
    }
    void TearDown() override { fs::remove_all(dir_); }

    fs::path write(const std::string& name, const std::string& text) {
        fs::path p = dir_ / name;
        fs::create_directories(p.parent_path());
        std::ofstream(p, std::ios::binary) << text;
        return p;
    }
    std::unique_ptr<Scene> load(const std::string& text) {
        return pbrt::load_scene_from_string(text, dir_);
    }
    // The world block `body` after kHeader, loaded from a file (so messages name it).
    std::unique_ptr<Scene> load_world(const std::string& body) {
        return load_scene(write("scene.pbrt", kHeader + body));
    }
    // The message of loading scene.pbrt = kHeader + body; fails the test if it loads.
    std::string world_error(const std::string& body) { return error_of(kHeader + body); }
    std::string error_of(const std::string& text) {
        try {
            load_scene(write("scene.pbrt", text));
        } catch (const SceneError& e) {
            return e.what();
        }
        ADD_FAILURE() << "loaded without error:\n" << text;
        return "";
    }
    // "scene.pbrt:N:" for line N of a world body (kHeader has 4 lines).
    std::string at_body_line(int n) {
        return (dir_ / "scene.pbrt").string() + ":" + std::to_string(n + 4) + ":";
    }

    fs::path dir_;
};

std::vector<pbrt::Token> tokens_of(const std::string& text) {
    pbrt::Tokenizer t(text, "t.pbrt");
    std::vector<pbrt::Token> out;
    while (auto tok = t.next()) out.push_back(*tok);
    return out;
}

TEST(PbrtTokenizer, StringsCommentsBracketsAndNumbers) {
    auto t = tokens_of(
        "Shape\"sphere\"# comment \"not a string\" [\n\"float radius\"[2.5e-1]"
        "\"string s\" \"a \\\"b\\\" \\\\ \\n#c\" -3 +4 .5[1 2]");
    ASSERT_EQ(t.size(), 15u);
    EXPECT_EQ(t[0].text, "Shape");
    EXPECT_FALSE(t[0].quoted);
    EXPECT_EQ(t[1].text, "sphere");
    EXPECT_TRUE(t[1].quoted);
    EXPECT_EQ(t[1].where.line, 1);
    EXPECT_EQ(t[2].text, "float radius");
    EXPECT_EQ(t[2].where.line, 2);  // the comment ended at the newline
    EXPECT_TRUE(t[3].is("["));
    EXPECT_EQ(t[4].text, "2.5e-1");
    EXPECT_TRUE(t[5].is("]"));
    EXPECT_EQ(t[7].text, "a \"b\" \\ \n#c");  // escapes; a # inside a string is no comment
    EXPECT_EQ(t[8].text, "-3");
    EXPECT_EQ(t[9].text, "+4");
    EXPECT_EQ(t[10].text, ".5");
    EXPECT_TRUE(t[11].is("["));
    EXPECT_EQ(t[12].text, "1");
    EXPECT_TRUE(t[14].is("]"));
}

TEST(PbrtTokenizer, MalformedStringsNameTheLine) {
    auto message = [](const std::string& text) {
        try {
            tokens_of(text);
        } catch (const SceneError& e) {
            return std::string(e.what());
        }
        return std::string("no error");
    };
    EXPECT_NE(message("A\nB \"open").find("t.pbrt:2: unterminated string"), std::string::npos);
    EXPECT_NE(message("\n\n\"a\nb\"").find("t.pbrt:3: a newline inside a string"),
              std::string::npos);
    EXPECT_NE(message("\"\\q\"").find("t.pbrt:1: unknown escape \\q"), std::string::npos);
}

TEST(PbrtParameters, ValuesWithAndWithoutBrackets) {
    pbrt::Tokenizer t(
        "\"float fov\" 45 \"integer n\" [ 3 ] \"bool b\" \"true\" \"bool c\" false "
        "\"rgb L\" [1 2 3] \"string s\" [\"x\"] \"point3 P\" [0 1 2 3 4 5] Next",
        "t.pbrt");
    pbrt::ParamList p = pbrt::ParamList::parse(t, "Test");
    EXPECT_EQ(p.get_float("fov", 0), 45);
    EXPECT_EQ(p.get_int("n", 0), 3);
    EXPECT_TRUE(p.get_bool("b", false));
    EXPECT_FALSE(p.get_bool("c", true));
    EXPECT_EQ(p.get_string("s", ""), "x");
    EXPECT_EQ(p.get_numbers("P", {"point3"}, 3).size(), 6u);
    EXPECT_EQ(p.get_float("absent", 7), 7);
    // "L" was not read: reported at its own line, with its type and name.
    try {
        p.check_all_used();
        ADD_FAILURE() << "unused parameter not reported";
    } catch (const SceneError& e) {
        EXPECT_NE(std::string(e.what()).find("\"rgb L\" is not supported"), std::string::npos)
            << e.what();
    }
    EXPECT_TRUE(t.next()->is("Next"));  // the list ends at the next directive
}

TEST(PbrtParameters, BadListsAreErrors) {
    auto message = [](const std::string& text) {
        try {
            pbrt::Tokenizer t(text, "t.pbrt");
            pbrt::ParamList p = pbrt::ParamList::parse(t, "Test");
            p.get_int("n", 0);
            p.get_float("f", 0);
        } catch (const SceneError& e) {
            return std::string(e.what());
        }
        return std::string("no error");
    };
    EXPECT_NE(message("\"float f\" 1 \n\"float f\" 2")
                  .find("t.pbrt:2: Test: parameter \"f\" given twice"),
              std::string::npos);
    EXPECT_NE(message("\"integer n\" 1.5").find("is not an integer"), std::string::npos);
    EXPECT_NE(message("\"float f\" [1 2]").find("expects 1 value, got 2"), std::string::npos);
    EXPECT_NE(message("\"float f\" [1 x]").find("\"x\" is not a number"), std::string::npos);
    EXPECT_NE(message("\"float f\" [1e99]").find("not a finite float"), std::string::npos);
    EXPECT_NE(message("\"colour f\" 1").find("unknown parameter type \"colour\""),
              std::string::npos);
    EXPECT_NE(message("\"float f\" [1").find("missing ]"), std::string::npos);
    EXPECT_NE(message("\"integer n\" \"3\"").find("expected a number"), std::string::npos);
    EXPECT_NE(message("\"string f\" 1").find("expected a quoted string"), std::string::npos);
    EXPECT_NE(message("\"string n\" \"1\"").find("\"n\": must be of type integer, not string"),
              std::string::npos);
}

// The world-space centre of a unit sphere placed with `transforms` (to compare with matrices
// computed here).
Vec3 sphere_center(const Scene& scene) {
    const Aabb b = scene.shapes().at(0)->bounds();
    return (b.lo + b.hi) * 0.5f;
}

void expect_near(const Vec3& a, const Vec3& b, float tol = 1e-5f) {
    EXPECT_NEAR(a.x, b.x, tol);
    EXPECT_NEAR(a.y, b.y, tol);
    EXPECT_NEAR(a.z, b.z, tol);
}

TEST_F(PbrtTest, TransformDirectivesPostMultiply) {
    // CTM = T(1,2,3) * Rz(90) * S(2): the origin goes to (1,2,3); the radius doubles.
    auto scene = load_world("Translate 1 2 3\nRotate 90 0 0 1\nScale 2 2 2\nShape \"sphere\"\n");
    expect_near(sphere_center(*scene), Vec3(1, 2, 3));
    EXPECT_NEAR(scene->shapes()[0]->surface_area(), 4 * kPi * 4, 1e-3);
    // Rz(90) * T(1,0,0): the origin goes to Rz(90) (1,0,0) = (0,1,0).
    scene = load_world("Rotate 90 0 0 1\nTranslate 1 0 0\nShape \"sphere\"\n");
    expect_near(sphere_center(*scene), Vec3(0, 1, 0));
    // Transform replaces the CTM; its 16 numbers are column-major (translation last).
    scene = load_world(
        "Translate 9 9 9\nTransform [1 0 0 0 0 1 0 0 0 0 1 0 2 3 4 1]\nShape \"sphere\"\n");
    expect_near(sphere_center(*scene), Vec3(2, 3, 4));
    // ConcatTransform post-multiplies: T(1,0,0) * [Rz(90) as columns] -> origin at (1,0,0),
    // and the point (1,0,0) of the object at (1,1,0).
    scene = load_world(
        "Translate 1 0 0\nConcatTransform [0 1 0 0 -1 0 0 0 0 0 1 0 0 0 0 1]\n"
        "Shape \"trianglemesh\" \"point3 P\" [0 0 0 1 0 0 0 0 1]\n");
    const Aabb b = scene->shapes()[0]->bounds();
    expect_near(b.lo, Vec3(1, 0, 0));
    expect_near(b.hi, Vec3(1, 1, 1));
    // Identity, AttributeBegin/End, CoordinateSystem/CoordSysTransform.
    scene = load_world(
        "Translate 5 0 0\nCoordinateSystem \"five\"\nIdentity\nAttributeBegin\nTranslate 0 7 0\n"
        "AttributeEnd\nCoordSysTransform \"five\"\nTranslate 0 0 1\nShape \"sphere\"\n");
    expect_near(sphere_center(*scene), Vec3(5, 0, 1));
    // TransformBegin/End (deprecated in pbrt-v4, still read) restore the CTM only.
    scene = load_world("TransformBegin\nTranslate 0 3 0\nTransformEnd\nShape \"sphere\"\n");
    expect_near(sphere_center(*scene), Vec3(0, 0, 0));
}

TEST(PbrtTransforms, LookAtIsWorldToCameraWithPbrtsAxes) {
    // Eye (1,2,3) looking along -z with up +y: forward (0,0,-1), right = cross(up, forward)
    // = (-1,0,0), up (0,1,0). World-to-camera rows are those axes; the eye maps to 0.
    const Transform t = pbrt::look_at(Vec3(1, 2, 3), Vec3(1, 2, 0), Vec3(0, 1, 0));
    const double expected[4][4] = {{-1, 0, 0, 1}, {0, 1, 0, -2}, {0, 0, -1, 3}, {0, 0, 0, 1}};
    for (size_t r = 0; r < 4; ++r)
        for (size_t c = 0; c < 4; ++c)
            EXPECT_NEAR(t.matrix()[r][c], expected[r][c], 1e-12) << r << "," << c;
    EXPECT_TRUE(pbrt::look_at(Vec3(0, 0, 0), Vec3(0, 1, 0), Vec3(0, 1, 0)).is_singular());
    // Rotate: right-handed, degrees.
    const Transform r = pbrt::rotate(90, Vec3(1, 0, 0));
    expect_near(r.apply_vector(Vec3(0, 1, 0)), Vec3(0, 0, 1));
}

TEST_F(PbrtTest, CameraOrientationAndFieldOfView) {
    // pbrt: camera space +x is the image's right. Looking from the origin along +z with +y up,
    // world +x is on the right, +y at the top. fov 60 spans the shorter axis (the height of a
    // 200 x 100 image): a point 30 degrees up lies on the top edge.
    const std::string camera =
        "LookAt 0 0 0  0 0 1  0 1 0\nCamera \"perspective\" \"float fov\" 60\n"
        "Film \"rgb\" \"integer xresolution\" 200 \"integer yresolution\" 100\n";
    auto scene = load(camera + "WorldBegin\n");
    const PerspectiveCamera& c = scene->camera();
    EXPECT_EQ(c.width(), 200);
    EXPECT_EQ(c.height(), 100);
    const auto right = c.raster_position(Vec3(1, 0, 5));
    ASSERT_TRUE(right);
    EXPECT_GT(right->x, 100.0f);
    const auto top = c.raster_position(Vec3(0, float(std::tan(29.9 * kPi / 180) * 5), 5));
    ASSERT_TRUE(top);
    EXPECT_NEAR(top->y, 0.0f, 0.5f);
    EXPECT_FALSE(c.raster_position(Vec3(0, float(std::tan(30.2 * kPi / 180) * 5), 5)));
    // A tall image: fov spans the width.
    scene = load(
        "LookAt 0 0 0  0 0 1  0 1 0\nCamera \"perspective\" \"float fov\" 60\n"
        "Film \"rgb\" \"integer xresolution\" 50 \"integer yresolution\" 100\nWorldBegin\n");
    const auto edge =
        scene->camera().raster_position(Vec3(float(std::tan(29.9 * kPi / 180) * 5), 0, 5));
    ASSERT_TRUE(edge);
    EXPECT_NEAR(edge->x, 50.0f, 0.5f);
    // The usual exporter convention `Scale -1 1 1` before LookAt mirrors the image.
    scene = load("Scale -1 1 1\n" + camera + "WorldBegin\n");
    const auto mirrored = scene->camera().raster_position(Vec3(1, 0, 5));
    ASSERT_TRUE(mirrored);
    EXPECT_LT(mirrored->x, 100.0f);
    // CoordSysTransform "camera" places things in camera space: 5 units in front of the eye.
    scene = load(camera +
                 "WorldBegin\nCoordSysTransform \"camera\"\nTranslate 0 0 5\nShape \"sphere\" "
                 "\"float radius\" 0.1\n");
    expect_near(sphere_center(*scene), Vec3(0, 0, 5));
}

TEST_F(PbrtTest, OptionsBlockSettings) {
    auto scene = load(
        "Integrator \"path\" \"integer maxdepth\" 3 \"bool regularize\" false\n"
        "Sampler \"halton\" \"integer pixelsamples\" 7\nCamera \"perspective\"\nWorldBegin\n");
    EXPECT_EQ(scene->settings.integrator, "pbrt:path");
    EXPECT_EQ(scene->settings.max_depth, 4);  // 3 bounces = 4 segments
    EXPECT_EQ(scene->settings.sample_count, 7);
    EXPECT_EQ(scene->camera().width(), 1280);  // pbrt's default film
    scene = load(
        "Sampler \"stratified\" \"integer xsamples\" 2 \"integer ysamples\" 3\n"
        "Integrator \"bdpt\"\nWorldBegin\n");
    EXPECT_EQ(scene->settings.sample_count, 6);
    EXPECT_EQ(scene->settings.integrator, "pbrt:bdpt");
    EXPECT_EQ(scene->settings.max_depth, 6);  // pbrt's default maxdepth 5
    scene = load("WorldBegin\n");
    EXPECT_EQ(scene->settings.integrator, "pbrt:volpath");  // pbrt's default integrator
    EXPECT_EQ(scene->settings.sample_count, 16);
}

TEST_F(PbrtTest, ShapesAreasAndBounds) {
    auto scene = load_world("Shape \"sphere\" \"float radius\" 2\n");
    EXPECT_NEAR(scene->shapes()[0]->surface_area(), 4 * kPi * 4, 1e-3);
    // disk: radius 3 at height 1 (object z), here rotated so its normal is +y.
    scene = load_world("Rotate -90 1 0 0\nShape \"disk\" \"float radius\" 3 \"float height\" 1\n");
    EXPECT_NEAR(scene->shapes()[0]->surface_area(), kPi * 9, 1e-3);
    Aabb b = scene->shapes()[0]->bounds();
    EXPECT_NEAR(b.lo.y, 1, 1e-4);
    EXPECT_NEAR(b.hi.x, 3, 1e-3);
    // trianglemesh: two triangles of a 2 x 3 rectangle, scaled by 2 in x.
    scene = load_world(
        "Scale 2 1 1\nShape \"trianglemesh\" \"point3 P\" [0 0 0 2 0 0 2 3 0 0 3 0] "
        "\"integer indices\" [0 1 2 0 2 3]\n");
    EXPECT_NEAR(scene->shapes()[0]->surface_area(), 12, 1e-4);
    b = scene->shapes()[0]->bounds();
    expect_near(b.hi, Vec3(4, 3, 0));
    // bilinearmesh: one planar patch (p00 p10 p01 p11) of 2 x 3.
    scene = load_world("Shape \"bilinearmesh\" \"point3 P\" [0 0 0 2 0 0 0 3 0 2 3 0]\n");
    EXPECT_NEAR(scene->shapes()[0]->surface_area(), 6, 1e-4);
    EXPECT_TRUE(dynamic_cast<const TriangleMesh*>(scene->shapes()[0].get()));
    // A non-planar patch stays a bilinear patch: the saddle z = x y over the unit square, whose
    // area is the integral of sqrt(1 + x^2 + y^2), 1.280789
    scene = load_world("Shape \"bilinearmesh\" \"point3 P\" [0 0 0 1 0 0 0 1 0 1 1 1]\n");
    ASSERT_TRUE(dynamic_cast<const BilinearPatches*>(scene->shapes()[0].get()));
    EXPECT_NEAR(scene->shapes()[0]->surface_area(), 1.280789, 2e-5);
    // plymesh, resolved against the scene's folder.
    write("models/quad.ply",
          "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
          "property float z\nelement face 1\nproperty list uchar int vertex_indices\n"
          "end_header\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3\n");
    scene = load_world("Shape \"plymesh\" \"string filename\" \"models/quad.ply\"\n");
    EXPECT_NEAR(scene->shapes()[0]->surface_area(), 1, 1e-5);
}

// pbrt-v4 reads a PLY file's quads as bilinear patches, corners v0 v1 v3 v2 as p00 p10 p01 p11
// (docs/reference/scene-format.md, "pbrt-v4 scenes"). Planar quads stay two triangles (the same
// surface); a file with a non-planar quad gives patches, beside a triangle mesh for its
// triangles, and the patch is the bilinearmesh with those corners, hit for hit.
TEST_F(PbrtTest, PlyQuadsAreBilinearPatchesAsInPbrt) {
    const std::string header =
        "ply\nformat ascii 1.0\nelement vertex 5\nproperty float x\nproperty float y\n"
        "property float z\nelement face 2\nproperty list uchar int vertex_indices\nend_header\n";
    // The saddle z = x y over the unit square as the face 0 1 3 2 (a quad's corners go round),
    // and a triangle beside it.
    write("models/saddle.ply", header + "0 0 0\n1 0 0\n0 1 0\n1 1 1\n2 0 0\n4 0 1 3 2\n3 1 4 3\n");
    auto scene = load_world("Shape \"plymesh\" \"string filename\" \"models/saddle.ply\"\n");
    ASSERT_EQ(scene->shapes().size(), 2u);
    const auto* patches = dynamic_cast<const BilinearPatches*>(scene->shapes()[0].get());
    ASSERT_TRUE(patches);
    EXPECT_NEAR(patches->surface_area(), 1.280789, 2e-5);
    const auto* triangles = dynamic_cast<const TriangleMesh*>(scene->shapes()[1].get());
    ASSERT_TRUE(triangles);
    // The triangle (1 0 0) (2 0 0) (1 1 1): base 1, height sqrt(2) over it.
    EXPECT_NEAR(triangles->surface_area(), std::sqrt(2.0) / 2, 1e-5);
    auto reference = load_world(
        "Shape \"bilinearmesh\" \"point3 P\" [0 0 0 1 0 0 0 1 0 1 1 1]\n"
        "Shape \"trianglemesh\" \"point3 P\" [1 0 0 2 0 0 1 1 1] \"integer indices\" [0 1 2]\n");
    int hits = 0;
    for (int i = 0; i < 16; ++i)
        for (int j = 0; j < 16; ++j) {
            const Ray ray(Vec3(-0.2f + 0.15f * i, -0.1f + 0.08f * j, 3.0f),
                          normalize(Vec3(0.1f, 0.05f, -1.0f)));
            SurfaceInteraction a, b;
            const bool hit_a = scene->intersect(ray, a), hit_b = reference->intersect(ray, b);
            ASSERT_EQ(hit_a, hit_b) << i << " " << j;
            if (!hit_a) continue;
            ++hits;
            EXPECT_EQ(a.t, b.t);
            EXPECT_EQ(a.geometric_normal.x, b.geometric_normal.x);
            EXPECT_EQ(a.geometric_normal.y, b.geometric_normal.y);
            EXPECT_EQ(a.geometric_normal.z, b.geometric_normal.z);
        }
    EXPECT_GT(hits, 100);
    // A planar quad: two triangles, as before.
    write("models/flat.ply", header + "0 0 0\n1 0 0\n0 1 0\n1 1 0\n2 0 0\n4 0 1 3 2\n3 1 4 3\n");
    scene = load_world("Shape \"plymesh\" \"string filename\" \"models/flat.ply\"\n");
    ASSERT_EQ(scene->shapes().size(), 1u);
    EXPECT_TRUE(dynamic_cast<const TriangleMesh*>(scene->shapes()[0].get()));
    EXPECT_NEAR(scene->shapes()[0]->surface_area(), 1.5, 1e-5);
    // As an area light, each part is its own light.
    scene = load_world(
        "AreaLightSource \"diffuse\" \"rgb L\" [1 1 1]\n"
        "Shape \"plymesh\" \"string filename\" \"models/saddle.ply\"\n");
    EXPECT_EQ(scene->lights().size(), 2u);
}

// The geometric normal where a ray from (0, 0, 5) towards the origin first hits the scene.
Vec3 normal_seen_from_above(const Scene& scene) {
    SurfaceInteraction si;
    if (!scene.intersect(Ray(Vec3(0.1f, 0.1f, 5), Vec3(0, 0, -1)), si)) return Vec3(0.0f);
    return si.geometric_normal;
}

TEST_F(PbrtTest, OrientationFollowsPbrt) {
    // Spheres and disks face outwards (+z here); ReverseOrientation flips them, and so does a
    // transform that swaps handedness (pbrt flips quadrics' normals then).
    EXPECT_GT(normal_seen_from_above(*load_world("Shape \"sphere\"\n")).z, 0.5f);
    EXPECT_LT(normal_seen_from_above(*load_world("ReverseOrientation\nShape \"sphere\"\n")).z,
              -0.5f);
    EXPECT_LT(normal_seen_from_above(*load_world("Scale -1 1 1\nShape \"sphere\"\n")).z, -0.5f);
    EXPECT_GT(normal_seen_from_above(*load_world("Shape \"disk\"\n")).z, 0.5f);
    // pbrt: the object normal +z, flipped (the transform swaps handedness) to -z, mirrored by the
    // transform back to +z.
    EXPECT_GT(normal_seen_from_above(*load_world("Scale 1 1 -1\nShape \"disk\"\n")).z, 0.5f);
    // Triangles without normals follow the winding, also under a mirror (pbrt flips the
    // world-space cross product back when the transform swaps handedness).
    const std::string tri = "Shape \"trianglemesh\" \"point3 P\" [-1 -1 0 1 -1 0 0 1 0]\n";
    EXPECT_GT(normal_seen_from_above(*load_world(tri)).z, 0.5f);
    EXPECT_GT(normal_seen_from_above(*load_world("Scale -1 1 1\n" + tri)).z, 0.5f);
    EXPECT_LT(normal_seen_from_above(*load_world("ReverseOrientation\n" + tri)).z, -0.5f);
}

TEST_F(PbrtTest, UnsupportedShapeVariantsAreErrors) {
    EXPECT_NE(world_error("Shape \"sphere\" \"float zmax\" 0.5\n")
                  .find(at_body_line(1) + " Shape \"sphere\": \"zmax\": partial shapes"),
              std::string::npos);
    EXPECT_NE(world_error("Shape \"cylinder\"\n").find("\"cylinder\" is not supported yet"),
              std::string::npos);
    EXPECT_NE(
        world_error(
            "Shape \"trianglemesh\" \"point3 P\" [0 0 0 1 0 0 0 1 0] \"integer indices\" [0 1 3]\n")
            .find("index 3 is out of range"),
        std::string::npos);
    EXPECT_NE(world_error("Shape \"plymesh\" \"string filename\" \"none.ply\"\n")
                  .find("mesh file not found"),
              std::string::npos);
    // A cut-out's alpha is supported (alpha_cutout_test.cpp); a bad one is refused at its line.
    EXPECT_NE(world_error("Shape \"sphere\" \"float radius\" 1\n  \"texture alpha\" \"none\"\n")
                  .find(at_body_line(2)),
              std::string::npos);
}

// The BSDF of the first shape, evaluated with wo = wi = the shading normal direction in the
// local frame (normal incidence), from the front and from the back.
Rgb f_normal(const Scene& scene, float side = 1) {
    const Bsdf* bsdf = scene.shapes().at(0)->bsdf;
    return bsdf->f(Vec3(0, 0, side), Vec3(0, 0, side), TransportMode::Radiance);
}

TEST_F(PbrtTest, MaterialsMapToOurBsdfs) {
    const std::string tri = "Shape \"trianglemesh\" \"point3 P\" [0 0 0 1 0 0 0 1 0]\n";
    // diffuse: albedo / pi, on both sides (pbrt's BxDFs are two-sided).
    auto scene = load_world("Material \"diffuse\" \"rgb reflectance\" [0.2 0.4 0.6]\n" + tri);
    for (float side : {1.0f, -1.0f}) {
        const Rgb f = f_normal(*scene, side);
        EXPECT_NEAR(f.r, 0.2 / kPi, 1e-6);
        EXPECT_NEAR(f.b, 0.6 / kPi, 1e-6);
    }
    // The default material: diffuse 0.5.
    scene = load_world(tri);
    EXPECT_NEAR(f_normal(*scene).g, 0.5 / kPi, 1e-6);
    // conductor with "reflectance": reflects r at normal incidence (eta 1, k from r).
    scene = load_world("Material \"conductor\" \"rgb reflectance\" [0.9 0.5 0.1]\n" + tri);
    auto s = scene->shapes()[0]->bsdf->sample(Vec3(0, 0, 1), 0.5f, Vec2(0.5f, 0.5f),
                                              TransportMode::Radiance);
    ASSERT_TRUE(s);
    EXPECT_NEAR(s->weight.r, 0.9, 1e-3);
    EXPECT_NEAR(s->weight.b, 0.1, 1e-3);
    // conductor with named metal spectra -> our RGB table; rough -> GGX with alpha sqrt(r).
    scene = load_world(
        "Material \"conductor\" \"spectrum eta\" \"metal-Ag-eta\" \"spectrum k\" \"metal-Ag-k\" "
        "\"float roughness\" 0.04\n" +
        tri);
    EXPECT_NE(scene->shapes()[0]->bsdf->to_string().find("0.2"), std::string::npos)
        << scene->shapes()[0]->bsdf->to_string();
    // dielectric: eta 1.5 -> normal-incidence reflectance ((1.5-1)/(1.5+1))^2 = 0.04: the
    // reflection is sampled with that probability and weight 1 (or F/p).
    scene = load_world("Material \"dielectric\" \"float eta\" 1.5\n" + tri);
    EXPECT_NE(scene->shapes()[0]->bsdf->to_string().find("1.5"), std::string::npos)
        << scene->shapes()[0]->bsdf->to_string();
    // pbrt's named dispersive BK7: its index at 589 nm, without dispersion.
    scene = load_world("Material \"dielectric\" \"spectrum eta\" \"glass-BK7\"\n" + tri);
    EXPECT_NE(scene->shapes()[0]->bsdf->to_string().find("1.50"), std::string::npos)
        << scene->shapes()[0]->bsdf->to_string();
    // coateddiffuse -> plastic: its diffuse part at normal incidence is below albedo/pi.
    scene = load_world("Material \"coateddiffuse\" \"rgb reflectance\" [0.5 0.5 0.5]\n" + tri);
    const Rgb f = f_normal(*scene);
    EXPECT_GT(f.g, 0.0f);
    EXPECT_LT(f.g, 0.5 / kPi);
    EXPECT_NE(scene->shapes()[0]->bsdf->to_string().find("twosided(plastic("), std::string::npos)
        << scene->shapes()[0]->bsdf->to_string();
    // A rough coating -> roughplastic with pbrt's GGX and alpha = sqrt(roughness).
    scene = load_world(
        "Material \"coateddiffuse\" \"rgb reflectance\" [0.5 0.5 0.5] \"float roughness\" 0.09 "
        "\"float eta\" 1.6\n" +
        tri);
    EXPECT_EQ(scene->shapes()[0]->bsdf->to_string(),
              "twosided(roughplastic(ggx, alpha 0.3, diffuse_reflectance [0.5, 0.5, 0.5], "
              "specular_reflectance [1, 1, 1], eta 1.6, nonlinear))");
    scene = load_world(
        "Material \"coateddiffuse\" \"float uroughness\" 0.1 \"float vroughness\" 0.3 "
        "\"bool remaproughness\" false\n" +
        tri);
    EXPECT_NE(scene->shapes()[0]->bsdf->to_string().find("roughplastic(ggx, alpha 0.2,"),
              std::string::npos)
        << scene->shapes()[0]->bsdf->to_string();
    // Named materials and mix with amount 0 or 1.
    scene = load_world(
        "MakeNamedMaterial \"a\" \"string type\" \"diffuse\" \"rgb reflectance\" [0.1 0.1 0.1]\n"
        "MakeNamedMaterial \"b\" \"string type\" \"diffuse\" \"rgb reflectance\" [0.3 0.3 0.3]\n"
        "MakeNamedMaterial \"m\" \"string type\" \"mix\" \"string materials\" [\"a\" \"b\"] "
        "\"float amount\" 1\nNamedMaterial \"m\"\n" +
        tri);
    EXPECT_NEAR(f_normal(*scene).g, 0.3 / kPi, 1e-6);
    // A fractional amount blends them (pbrt picks "b" with probability amount).
    scene = load_world(
        "MakeNamedMaterial \"a\" \"string type\" \"diffuse\" \"rgb reflectance\" [0.1 0.1 0.1]\n"
        "MakeNamedMaterial \"b\" \"string type\" \"diffuse\" \"rgb reflectance\" [0.3 0.3 0.3]\n"
        "MakeNamedMaterial \"m\" \"string type\" \"mix\" \"string materials\" [\"a\" \"b\"] "
        "\"float amount\" 0.25\nNamedMaterial \"m\"\n" +
        tri);
    EXPECT_NEAR(f_normal(*scene).g, (0.75 * 0.1 + 0.25 * 0.3) / kPi, 1e-6);
    EXPECT_EQ(scene->shapes()[0]->bsdf->to_string().rfind("blendbsdf(weight 0.25, ", 0), 0u)
        << scene->shapes()[0]->bsdf->to_string();
    // ... also with a float texture as the amount.
    scene = load_world(
        "MakeNamedMaterial \"a\" \"string type\" \"diffuse\" \"rgb reflectance\" [0.1 0.1 0.1]\n"
        "MakeNamedMaterial \"b\" \"string type\" \"diffuse\" \"rgb reflectance\" [0.3 0.3 0.3]\n"
        "Texture \"t\" \"float\" \"constant\" \"float value\" 0.5\n"
        "MakeNamedMaterial \"m\" \"string type\" \"mix\" \"string materials\" [\"a\" \"b\"] "
        "\"texture amount\" \"t\"\nNamedMaterial \"m\"\n" +
        tri);
    EXPECT_NE(scene->shapes()[0]->bsdf->to_string().find("blendbsdf"), std::string::npos)
        << scene->shapes()[0]->bsdf->to_string();
}

TEST_F(PbrtTest, MaterialErrorsNameTheParameter) {
    const std::string tri = "Shape \"trianglemesh\" \"point3 P\" [0 0 0 1 0 0 0 1 0]\n";
    EXPECT_NE(
        world_error("Material \"diffuse\"\n \"rgb reflectance\" [1 1 1]\n \"float sigma\" 2\n")
            .find(at_body_line(3) +
                  " Material \"diffuse\": parameter \"float sigma\" is not supported"),
        std::string::npos);
    EXPECT_NE(world_error("Material \"measured\"\n").find("not supported yet"), std::string::npos);
    EXPECT_NE(world_error("Material \"velvet\"\n")
                  .find(at_body_line(1) + " Material \"velvet\": unknown material"),
              std::string::npos);
    EXPECT_NE(
        world_error(
            "MakeNamedMaterial \"m\" \"string type\" \"mix\" \"string materials\" [\"a\" \"b\"]\n")
            .find("MakeNamedMaterial \"m\": \"materials\": unknown named material \"a\""),
        std::string::npos);
    EXPECT_NE(world_error("NamedMaterial \"nope\"\n").find("unknown material \"nope\""),
              std::string::npos);
    EXPECT_NE(world_error("Material \"dielectric\" \"spectrum eta\" \"glass-BF10\"\n")
                  .find("named spectra"),
              std::string::npos);
    EXPECT_NE(world_error("Material \"diffuse\" \"spectrum reflectance\" [400 0.1 700 0.9]\n")
                  .find("vary with wavelength"),
              std::string::npos);
}

// The radiance the scene's first light sends along a ray from `origin` in direction `dir` when
// the ray hits its shape (black when it hits the back).
float emitted_green(const Scene& scene, const Vec3& origin, const Vec3& dir) {
    SurfaceInteraction si;
    if (!scene.intersect(Ray(origin, dir), si)) return -1;
    return scene.lights()[0]->radiance(si.p, si.geometric_normal, dir).radiance.g;
}

TEST_F(PbrtTest, LightsEmitRgbTimesScale) {
    const std::string quad =
        "Shape \"trianglemesh\" \"point3 P\" [0 0 0 1 0 0 1 1 0 0 1 0] \"integer indices\" "
        "[0 1 2 0 2 3]\n";
    // Area light: radiance L * scale on the front (the winding's side, +z here) only.
    auto scene = load_world(
        "AttributeBegin\nAreaLightSource \"diffuse\" \"rgb L\" [1 2 3] \"float scale\" 2\n" + quad +
        "AttributeEnd\n");
    ASSERT_EQ(scene->lights().size(), 1u);
    const Light& area = *scene->lights()[0];
    EXPECT_NEAR(area.radiance(Vec3(0.5f, 0.5f, 0), Vec3(0, 0, 1), Vec3(0, 0, -1)).radiance.b, 6,
                1e-5);
    EXPECT_EQ(area.radiance(Vec3(0.5f, 0.5f, 0), Vec3(0, 0, 1), Vec3(0, 0, 1)).radiance.b, 0);
    // ReverseOrientation flips the emitting side.
    scene =
        load_world("ReverseOrientation\nAreaLightSource \"diffuse\" \"rgb L\" [1 1 1]\n" + quad);
    EXPECT_EQ(emitted_green(*scene, Vec3(0.5f, 0.4f, 1), Vec3(0, 0, -1)), 0);
    EXPECT_NEAR(emitted_green(*scene, Vec3(0.5f, 0.4f, -1), Vec3(0, 0, 1)), 1, 1e-6);
    scene = load_world("AreaLightSource \"diffuse\" \"rgb L\" [1 1 1]\n" + quad);
    EXPECT_NEAR(emitted_green(*scene, Vec3(0.5f, 0.4f, 1), Vec3(0, 0, -1)), 1, 1e-6);
    EXPECT_EQ(emitted_green(*scene, Vec3(0.5f, 0.4f, -1), Vec3(0, 0, 1)), 0);
    // Normals decide the side when the mesh has them (pbrt orients the triangle to N).
    scene = load_world(
        "AreaLightSource \"diffuse\" \"rgb L\" [1 1 1]\n"
        "Shape \"trianglemesh\" \"point3 P\" [0 0 0 1 0 0 0 1 0] \"normal N\" [0 0 -1 0 0 -1 0 0 "
        "-1]\n");
    EXPECT_NEAR(emitted_green(*scene, Vec3(0.2f, 0.2f, -1), Vec3(0, 0, 1)), 1, 1e-6);
    EXPECT_EQ(emitted_green(*scene, Vec3(0.2f, 0.2f, 1), Vec3(0, 0, -1)), 0);
    // Point light: intensity I * scale at the transformed "from": power 4 pi I.
    scene = load_world(
        "Translate 0 1 0\nLightSource \"point\" \"rgb I\" [1 2 3] \"float scale\" 0.5 \"point3 "
        "from\" [1 0 0]\n");
    ASSERT_EQ(scene->lights().size(), 1u);
    EXPECT_NEAR(scene->lights()[0]->power().g, 4 * kPi * 1, 1e-4);
    LightIlluminateSample ls;
    ASSERT_TRUE(scene->lights()[0]->illuminate(Vec3(1, 3, 0), Vec2(0.5f, 0.5f), ls));
    // infinite with L: a constant background light.
    scene = load_world("LightSource \"infinite\" \"rgb L\" [0.5 0.5 0.5]\n");
    EXPECT_EQ(scene->background_lights().size(), 1u);
    scene = load_world(
        "LightSource \"distant\" \"point3 to\" [0 -1 0] \"rgb L\" [3 3 3]\nLightSource \"spot\" "
        "\"point3 from\" [0 2 0] \"point3 to\" [0 0 0]\n");
    EXPECT_EQ(scene->lights().size(), 2u);
}

// pbrt-v4's image infinite light: a square equal-area octahedral map in light space. Its
// quadrants hold the directions by the signs of (x, y): top-left x < 0, y < 0 (rows top first),
// top-right x > 0, y < 0, bottom-left x < 0, y > 0, bottom-right both positive.
TEST_F(PbrtTest, ImageInfiniteLightIsEqualAreaOctahedral) {
    Image image(8, 8);
    const Rgb colours[4] = {Rgb(1, 0, 0), Rgb(0, 1, 0), Rgb(0, 0, 1), Rgb(1, 1, 0)};
    for (int y = 0; y < 8; ++y)
        for (int x = 0; x < 8; ++x) image.set(size_t(y) * 8 + x, colours[(y / 4) * 2 + x / 4]);
    write_exr(dir_ / "sky.exr", image);
    auto seen = [](const Scene& scene, const Vec3& d) {
        return scene.background_lights()
            .at(0)
            ->radiance(Vec3(0.0f), Vec3(0.0f), normalize(d))
            .radiance;
    };
    auto scene =
        load_world("LightSource \"infinite\" \"string filename\" \"sky.exr\" \"float scale\" 2\n");
    for (float z : {0.3f, -0.3f}) {
        EXPECT_NEAR(seen(*scene, Vec3(-1, -1, z)).r, 2, 1e-5);
        EXPECT_NEAR(seen(*scene, Vec3(1, -1, z)).g, 2, 1e-5);
        EXPECT_NEAR(seen(*scene, Vec3(-1, 1, z)).b, 2, 1e-5);
        EXPECT_NEAR(seen(*scene, Vec3(1, 1, z)).g, 2, 1e-5);
        EXPECT_NEAR(seen(*scene, Vec3(1, 1, z)).b, 0, 1e-5);
    }
    // The CTM places the map: with Rotate 90 about z, world (1, 1) is light (1, -1).
    scene =
        load_world("Rotate 90 0 0 1\nLightSource \"infinite\" \"string filename\" \"sky.exr\"\n");
    EXPECT_NEAR(seen(*scene, Vec3(1, 1, 0.3f)).g, 1, 1e-5);
    EXPECT_NEAR(seen(*scene, Vec3(1, 1, 0.3f)).r, 0, 1e-5);
    write_exr(dir_ / "wide.exr", Image(4, 2));
    EXPECT_NE(world_error("LightSource \"infinite\" \"string filename\" \"wide.exr\"\n")
                  .find("must be square"),
              std::string::npos);
}

// pbrt-v4 normalises a blackbody light to unit luminance: our RGB is the blackbody's
// chromaticity at luminance 1 (times scale).
TEST_F(PbrtTest, BlackbodyLightsHaveUnitLuminance) {
    auto luminance = [](const Rgb& c) { return 0.2126f * c.r + 0.7152f * c.g + 0.0722f * c.b; };
    for (double kelvin : {2700.0, 4000.0, 6504.0, 10000.0}) {
        const Rgb c = *pbrt::blackbody_rgb(kelvin);
        EXPECT_NEAR(luminance(c), 1.0f, 2e-3f) << kelvin;
    }
    const Rgb warm = *pbrt::blackbody_rgb(3000), cool = *pbrt::blackbody_rgb(10000);
    EXPECT_GT(warm.r, warm.g);
    EXPECT_GT(warm.g, warm.b);
    EXPECT_GT(cool.b, cool.r);
    const Rgb d65ish = *pbrt::blackbody_rgb(6504);  // near white
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(d65ish[c], 1.0f, 0.1f) << c;
    EXPECT_FALSE(pbrt::blackbody_rgb(1000));
    auto scene = load_world("LightSource \"point\" \"blackbody I\" 3000 \"float scale\" 2\n");
    EXPECT_NEAR(luminance(scene->lights()[0]->power()) / float(4 * kPi), 2.0f, 5e-3f);
}

TEST_F(PbrtTest, LightErrors) {
    EXPECT_NE(world_error("AreaLightSource \"diffuse\" \"bool twosided\" true\nShape \"sphere\"\n")
                  .find("two-sided area lights are not supported yet"),
              std::string::npos);
    EXPECT_NE(world_error("LightSource \"infinite\"\n \"string filename\" \"sky.exr\"\n")
                  .find(at_body_line(2) +
                        " LightSource \"infinite\": \"filename\": image file not found"),
              std::string::npos);
    EXPECT_NE(world_error("LightSource \"point\" \"float power\" 10\n").find("\"power\""),
              std::string::npos);
    EXPECT_NE(world_error("LightSource \"point\" \"blackbody I\" 1000\n").find("1667 to 25000 K"),
              std::string::npos);
    EXPECT_NE(world_error("LightSource \"goniometric\"\n").find("not supported yet"),
              std::string::npos);
}

TEST_F(PbrtTest, IncludeAndImport) {
    write("inc/materials.pbrt",
          "MakeNamedMaterial \"grey\" \"string type\" \"diffuse\" \"rgb reflectance\" [0.25 0.25 "
          "0.25]\n");
    // Names resolve against the main scene's folder, also inside included files.
    write("inc/shapes.pbrt",
          "Import \"inc/materials.pbrt\"\nNamedMaterial \"grey\"\nShape \"sphere\"\n");
    auto scene = load_world("Include \"inc/shapes.pbrt\"\n");
    ASSERT_EQ(scene->shapes().size(), 1u);
    EXPECT_NEAR(
        scene->shapes()[0]->bsdf->f(Vec3(0, 0, 1), Vec3(0, 0, 1), TransportMode::Radiance).r,
        0.25 / kPi, 1e-6);
    // An error inside an included file names that file and line.
    write("inc/bad.pbrt", "Shape \"sphere\"\n\nShape \"cone\"\n");
    EXPECT_NE(world_error("Include \"inc/bad.pbrt\"\n")
                  .find((dir_ / "inc/bad.pbrt").string() + ":3: Shape \"cone\": unknown shape"),
              std::string::npos)
        << world_error("Include \"inc/bad.pbrt\"\n");
    EXPECT_NE(world_error("Include \"missing.pbrt\"\n").find(at_body_line(1) + " file not found"),
              std::string::npos);
    write("inc/loop.pbrt", "Include \"inc/loop.pbrt\"\n");
    EXPECT_NE(world_error("Include \"inc/loop.pbrt\"\n").find("include cycle"), std::string::npos);
    // The client's bundle summary follows includes and lists files, not Film's output.
    write("inc/mesh.pbrt", "Shape \"plymesh\" \"string filename\" [\"m.ply\"]\n");
    const fs::path main = write("main.pbrt",
                                "Film \"rgb\" \"string filename\" \"out.exr\"\n"
                                "Sampler \"sobol\" \"integer pixelsamples\" [ 32 ]\n"
                                "Integrator \"bdpt\"\nWorldBegin\nInclude \"inc/mesh.pbrt\"\n");
    const pbrt::SceneSummary summary = pbrt::summarize(main);
    ASSERT_EQ(summary.files.size(), 2u);
    EXPECT_EQ(summary.files[0], dir_ / "inc/mesh.pbrt");
    EXPECT_EQ(summary.files[1], dir_ / "m.ply");
    EXPECT_EQ(summary.sample_count, 32);
    EXPECT_EQ(summary.integrator, "pbrt:bdpt");
}

TEST_F(PbrtTest, ConfinedLoadRefusesFilesOutsideTheFolderAsMitsubaDoes) {
    // Both loaders check confinement with one FolderConfinement (file_resolver.h): the same
    // file outside the job's folder is refused with the same message.
    write("outside.ply", "");
    write("outside.pbrt", "");
    write("job/inside.pbrt", "Shape \"sphere\"\n");
    const fs::path job = dir_ / "job";
    auto confined_error = [&](const fs::path& scene) -> std::string {
        try {
            load_scene(scene, {}, job);
        } catch (const SceneError& e) {
            return e.what();
        }
        return "(no error)";
    };
    const std::string outside = (dir_ / "outside.ply").string() + " is outside " +
                                fs::weakly_canonical(job).string() +
                                " (a job reads only the files of its bundle)";
    const fs::path pbrt_scene = write(
        "job/scene.pbrt", kHeader + "Shape \"plymesh\" \"string filename\" \"../outside.ply\"\n");
    EXPECT_EQ(confined_error(pbrt_scene), pbrt_scene.string() + ":5: " + outside);
    const fs::path xml_scene =
        write("job/scene.xml",
              "<scene version=\"3.0.0\"><sensor type=\"perspective\"/>\n<shape type=\"ply\">"
              "<string name=\"filename\" value=\"../outside.ply\"/></shape></scene>");
    EXPECT_NE(confined_error(xml_scene).find("parameter \"filename\": " + outside),
              std::string::npos)
        << confined_error(xml_scene);
    EXPECT_EQ(confined_error(write("job/inc.pbrt", kHeader + "Include \"../outside.pbrt\"\n")),
              (dir_ / "job/inc.pbrt").string() + ":5: " + (dir_ / "outside.pbrt").string() +
                  " is outside " + fs::weakly_canonical(job).string() +
                  " (a job reads only the files of its bundle)");
    EXPECT_NO_THROW(
        load_scene(write("job/ok.pbrt", kHeader + "Include \"inside.pbrt\"\n"), {}, job));
}

TEST_F(PbrtTest, DirectiveErrorsNameFileAndLine) {
    EXPECT_NE(world_error("Shape \"sphere\"\nFrobnicate 3\n")
                  .find(at_body_line(2) + " unknown directive \"Frobnicate\""),
              std::string::npos);
    EXPECT_NE(
        error_of("Shape \"sphere\"\n").find("scene.pbrt:1: Shape is only allowed after WorldBegin"),
        std::string::npos);
    EXPECT_NE(world_error("Camera \"perspective\"\n").find("only allowed before WorldBegin"),
              std::string::npos);
    EXPECT_NE(error_of("Camera \"orthographic\"\nWorldBegin\n")
                  .find("scene.pbrt:1: Camera \"orthographic\" is not supported yet"),
              std::string::npos);
    EXPECT_NE(error_of("Camera \"perspective\" \"float lensradius\" -0.1\nWorldBegin\n")
                  .find("\"lensradius\""),
              std::string::npos);
    EXPECT_NE(error_of("Camera \"perspective\" \"float lensradius\" 0.1 \"float focaldistance\" 0"
                       "\nWorldBegin\n")
                  .find("\"focaldistance\""),
              std::string::npos);
    EXPECT_NE(error_of("Film \"rgb\" \"float iso\" 400\nWorldBegin\n").find("\"iso\""),
              std::string::npos);
    EXPECT_NE(
        error_of("Film \"rgb\" \"integer cropwindow\" [0 1 0 1]\nWorldBegin\n").find("cropwindow"),
        std::string::npos);
    EXPECT_NE(world_error("AttributeEnd\n").find("AttributeEnd without AttributeBegin"),
              std::string::npos);
    EXPECT_NE(world_error("AttributeBegin\n")
                  .find(at_body_line(1) + " AttributeBegin without AttributeEnd"),
              std::string::npos);
    EXPECT_NE(
        world_error("ObjectBegin \"x\"\n").find(at_body_line(1) + " ObjectBegin without ObjectEnd"),
        std::string::npos);
    EXPECT_NE(world_error("Translate 1 2\nShape \"sphere\"\n")
                  .find(at_body_line(2) + " \"Translate\": \"Shape\" is not a number"),
              std::string::npos);
    EXPECT_NE(world_error("Rotate 10 0 0 0\n").find("the axis is zero"), std::string::npos);
    EXPECT_NE(world_error("Transform [1 2 3]\n").find("Transform: expected 16 numbers, got 3"),
              std::string::npos);
    EXPECT_NE(world_error("\"sphere\"\n").find("expected a directive"), std::string::npos);
    EXPECT_NE(error_of("Camera \"perspective\"\n").find("no WorldBegin"), std::string::npos);
    EXPECT_NE(error_of("WorldEnd\n").find("pbrt-v3"), std::string::npos);
    // Ignored with a warning, not refused: Option, ColorSpace srgb, Accelerator, PixelFilter.
    EXPECT_NO_THROW(
        load("Option \"bool disablepixeljitter\" true\nColorSpace \"srgb\"\n"
             "Accelerator \"bvh\" \"integer maxnodeprims\" 4\nPixelFilter \"gaussian\"\n"
             "WorldBegin\n"));
    // -D defines are Mitsuba's.
    try {
        load_scene(write("d.pbrt", "WorldBegin\n"), {{"spp", "4"}});
        ADD_FAILURE() << "defines accepted";
    } catch (const SceneError& e) {
        EXPECT_NE(std::string(e.what()).find("pbrt files take no parameters"), std::string::npos);
    }
}

TEST_F(PbrtTest, Media) {
    // homogeneous: sigma_t = scale (sigma_a + sigma_s), sigma_s = scale sigma_s; inside a
    // sphere (MediumInterface inside outside) with the interface material.
    auto scene = load_world(
        "MakeNamedMedium \"fog\" \"string type\" \"homogeneous\" \"rgb sigma_a\" [0.1 0.2 0.3] "
        "\"rgb sigma_s\" [1 1 1] \"float scale\" 2 \"float g\" 0.5\n"
        "AttributeBegin\nMediumInterface \"fog\" \"\"\nMaterial \"interface\"\nShape \"sphere\"\n"
        "AttributeEnd\nShape \"disk\"\n");
    EXPECT_TRUE(scene->has_media());
    const Shape& sphere = *scene->shapes()[0];
    ASSERT_NE(sphere.interior, nullptr);
    EXPECT_EQ(sphere.exterior, nullptr);
    EXPECT_NEAR(sphere.interior->sigma_t(Vec3(0.0f)).b, 2 * 1.3, 1e-5);
    EXPECT_NEAR(sphere.interior->sigma_s(Vec3(0.0f)).r, 2, 1e-5);
    EXPECT_EQ(sphere.bsdf->to_string(), "null");       // "interface": an index-matched boundary
    EXPECT_EQ(scene->shapes()[1]->interior, nullptr);  // after AttributeEnd: no interface
    // uniformgrid: sigma_t(p) = scale (sigma_a + sigma_s) density(p) over [p0, p1], placed by
    // the CTM; cell-centred trilinear lookups (2 x 1 x 1 voxels: 1 at x = 0.25, 3 at 0.75).
    scene = load_world(
        "Translate 10 0 0\nMakeNamedMedium \"smoke\" \"string type\" \"uniformgrid\" "
        "\"integer nx\" 2 \"float density\" [1 3] \"rgb sigma_a\" [0 0 0] \"rgb sigma_s\" [2 2 2] "
        "\"point3 p0\" [0 0 0] \"point3 p1\" [2 1 1]\nIdentity\n"
        "MediumInterface \"smoke\" \"\"\nMaterial \"interface\"\n"
        "Shape \"trianglemesh\" \"point3 P\" [0 0 0 1 0 0 0 1 0]\n");
    const Medium* smoke = scene->shapes()[0]->interior;
    ASSERT_NE(smoke, nullptr);
    EXPECT_NEAR(smoke->sigma_t(Vec3(10.5f, 0.5f, 0.5f)).g, 2 * 1, 1e-5);
    EXPECT_NEAR(smoke->sigma_t(Vec3(11.0f, 0.5f, 0.5f)).g, 2 * 2, 1e-5);
    EXPECT_NEAR(smoke->sigma_t(Vec3(11.5f, 0.5f, 0.5f)).g, 2 * 3, 1e-5);
    EXPECT_NEAR(smoke->sigma_s(Vec3(11.5f, 0.5f, 0.5f)).g, 2 * 3, 1e-5);  // albedo 1
    // The camera sits in the outside medium current at Camera.
    scene = load(
        "MakeNamedMedium \"air\" \"string type\" \"homogeneous\" \"rgb sigma_a\" [0.01 0.01 0.01] "
        "\"rgb sigma_s\" [0 0 0]\nMediumInterface \"air\"\nCamera \"perspective\"\nWorldBegin\n");
    EXPECT_NE(scene->camera_medium(), nullptr);
    // Errors.
    EXPECT_NE(world_error("MediumInterface \"nope\" \"\"\n")
                  .find(at_body_line(1) + " MediumInterface: unknown medium \"nope\""),
              std::string::npos);
    // Emission: Le times Lescale (a float, or for uniformgrid a grid on the density's lattice,
    // not multiplied by the density), as `radiance`; sigma_a Le is the source term in both.
    scene = load_world(
        "MakeNamedMedium \"glow\" \"string type\" \"homogeneous\" \"rgb sigma_a\" [1 1 1] "
        "\"rgb Le\" [0.5 1 2] \"float Lescale\" 3\nMediumInterface \"glow\" \"\"\n"
        "Material \"interface\"\nShape \"trianglemesh\" \"point3 P\" [0 0 0 1 0 0 0 1 0]\n");
    const Medium* glow = scene->shapes()[0]->interior;
    ASSERT_NE(glow, nullptr);
    EXPECT_TRUE(glow->is_emissive());
    EXPECT_NEAR(glow->radiance(Vec3(0.0f)).r, 1.5, 1e-6);
    EXPECT_NEAR(glow->radiance(Vec3(0.0f)).b, 6, 1e-6);
    scene = load_world(
        "Translate 10 0 0\nMakeNamedMedium \"flame\" \"string type\" \"uniformgrid\" "
        "\"integer nx\" 2 \"float density\" [1 3] \"float Lescale\" [2 4] \"rgb Le\" [1 0.5 0] "
        "\"point3 p0\" [0 0 0] \"point3 p1\" [2 1 1]\nIdentity\n"
        "MediumInterface \"flame\" \"\"\nMaterial \"interface\"\n"
        "Shape \"trianglemesh\" \"point3 P\" [0 0 0 1 0 0 0 1 0]\n");
    const Medium* flame = scene->shapes()[0]->interior;
    ASSERT_NE(flame, nullptr);
    EXPECT_TRUE(flame->is_emissive());
    EXPECT_NEAR(flame->radiance(Vec3(10.5f, 0.5f, 0.5f)).r, 2, 1e-5);  // voxel 0's centre
    EXPECT_NEAR(flame->radiance(Vec3(11.0f, 0.5f, 0.5f)).r, 3, 1e-5);  // halfway
    EXPECT_NEAR(flame->radiance(Vec3(11.5f, 0.5f, 0.5f)).g, 2, 1e-5);  // voxel 1: 4 x 0.5
    EXPECT_NEAR(flame->radiance(Vec3(11.5f, 0.5f, 0.5f)).b, 0, 1e-6);
    // A constant Lescale on a grid; Le absent: no emission whatever Lescale says.
    scene = load_world(
        "MakeNamedMedium \"a\" \"string type\" \"uniformgrid\" \"float density\" [1] "
        "\"rgb Le\" [1 1 1] \"float Lescale\" 0.5\nMediumInterface \"a\" \"\"\n"
        "Material \"interface\"\nShape \"trianglemesh\" \"point3 P\" [0 0 0 1 0 0 0 1 0]\n");
    EXPECT_NEAR(scene->shapes()[0]->interior->radiance(Vec3(0.5f)).g, 0.5, 1e-6);
    scene = load_world(
        "MakeNamedMedium \"b\" \"string type\" \"homogeneous\" \"float Lescale\" 4\n"
        "MediumInterface \"b\" \"\"\nMaterial \"interface\"\n"
        "Shape \"trianglemesh\" \"point3 P\" [0 0 0 1 0 0 0 1 0]\n");
    EXPECT_FALSE(scene->shapes()[0]->interior->is_emissive());
    // A blackbody Le is its unit-luminance colour (as for lights), times Lescale.
    scene = load_world(
        "MakeNamedMedium \"c\" \"string type\" \"homogeneous\" \"blackbody Le\" 3000 "
        "\"float Lescale\" 2\nMediumInterface \"c\" \"\"\nMaterial \"interface\"\n"
        "Shape \"trianglemesh\" \"point3 P\" [0 0 0 1 0 0 0 1 0]\n");
    const Rgb warm = *pbrt::blackbody_rgb(3000);
    EXPECT_NEAR(scene->shapes()[0]->interior->radiance(Vec3(0.0f)).r, 2 * warm.r, 1e-5);
    EXPECT_NEAR(scene->shapes()[0]->interior->radiance(Vec3(0.0f)).b, 2 * warm.b, 1e-5);
    EXPECT_NE(world_error("MakeNamedMedium \"m\" \"string type\" \"homogeneous\" \"rgb Le\" "
                          "[1 -1 1]\n")
                  .find("Le"),
              std::string::npos);
    EXPECT_NE(world_error("MakeNamedMedium \"m\" \"string type\" \"uniformgrid\" \"integer nx\" "
                          "2 \"float density\" [1 1] \"float Lescale\" [1 2 3]\n")
                  .find("expects 1 or nx * ny * nz = 2 values, got 3"),
              std::string::npos);
    EXPECT_NE(world_error("MakeNamedMedium \"m\" \"string type\" \"uniformgrid\" \"float "
                          "density\" [1] \"float temperature\" [1000]\n")
                  .find("temperature grids is not supported yet"),
              std::string::npos);
    EXPECT_NE(world_error("MakeNamedMedium \"m\" \"string type\" \"uniformgrid\" \"integer nx\" 2 "
                          "\"float density\" [1]\n")
                  .find("expects nx * ny * nz = 2 values, got 1"),
              std::string::npos);
    EXPECT_NE(
        world_error("MakeNamedMedium \"m\" \"string type\" \"cloud\"\n").find("not supported yet"),
        std::string::npos);
}

TEST_F(PbrtTest, Textures) {
    const std::string quad =
        "Shape \"trianglemesh\" \"point3 P\" [0 0 0 1 0 0 1 1 0 0 1 0] \"point2 uv\" [0 0 1 0 1 1 "
        "0 1] "
        "\"integer indices\" [0 1 2 0 2 3]\n";
    // checkerboard: pbrt's tex1 where floor(s) + floor(t) is even.
    auto scene = load_world(
        "Texture \"c\" \"spectrum\" \"checkerboard\" \"float uscale\" 2 \"float vscale\" 2 "
        "\"rgb tex1\" [1 0 0] \"rgb tex2\" [0 0 1]\n"
        "Material \"diffuse\" \"texture reflectance\" \"c\"\n" +
        quad);
    const Bsdf* bsdf = scene->shapes()[0]->bsdf;
    // Our uv has v flipped: pbrt (s, t) = (u, 1 - v).
    auto albedo_at = [&](float s, float t) {
        auto at = bsdf->at(Vec2(s, 1 - t));
        const Bsdf* b = at ? at.get() : bsdf;
        return b->f(Vec3(0, 0, 1), Vec3(0, 0, 1), TransportMode::Radiance) * float(kPi);
    };
    EXPECT_NEAR(albedo_at(0.2f, 0.2f).r, 1, 1e-5);  // floor(0.4) + floor(0.4) = 0: tex1
    EXPECT_NEAR(albedo_at(0.7f, 0.2f).b, 1, 1e-5);  // 1 + 0: tex2
    EXPECT_NEAR(albedo_at(0.7f, 0.7f).r, 1, 1e-5);  // 1 + 1: tex1
    EXPECT_NEAR(albedo_at(0.2f, 0.7f).b, 1, 1e-5);  // 0 + 1: tex2
    // imagemap: pbrt looks the image up at (s, 1 - t), row 0 on top: t near 1 is the top row.
    Image image(2, 2);
    image.set(0, Rgb(1, 0, 0));  // top left
    image.set(1, Rgb(0, 1, 0));  // top right
    image.set(2, Rgb(0, 0, 1));  // bottom left
    image.set(3, Rgb(1, 1, 1));  // bottom right
    write_exr(dir_ / "tex.exr", image);
    scene = load_world(
        "Texture \"i\" \"spectrum\" \"imagemap\" \"string filename\" \"tex.exr\" "
        "\"string filter\" \"point\" \"float uscale\" 2\n"
        "Material \"diffuse\" \"texture reflectance\" \"i\"\n" +
        quad);
    bsdf = scene->shapes()[0]->bsdf;
    EXPECT_NEAR(albedo_at(0.1f, 0.9f).r, 1, 1e-5);  // s' = 0.2, top: red
    EXPECT_NEAR(albedo_at(0.1f, 0.9f).g, 0, 1e-5);
    EXPECT_NEAR(albedo_at(0.3f, 0.9f).g, 1, 1e-5);  // s' = 0.6: green
    EXPECT_NEAR(albedo_at(0.3f, 0.9f).r, 0, 1e-5);
    EXPECT_NEAR(albedo_at(0.1f, 0.2f).b, 1, 1e-5);  // bottom: blue
    EXPECT_NEAR(albedo_at(0.1f, 0.2f).r, 0, 1e-5);
    EXPECT_NEAR(albedo_at(0.8f, 0.2f).g, 1, 1e-5);  // s' = 1.6, repeat: 0.6: white
    EXPECT_NE(world_error("Texture \"t\" \"spectrum\" \"marble\"\n").find("not supported yet"),
              std::string::npos);
    EXPECT_NE(world_error("Material \"diffuse\" \"texture reflectance\" \"none\"\n")
                  .find("unknown texture \"none\""),
              std::string::npos);
}

// Fuzzing finding (tests/fuzz/corpus/pbrt/finding-camera-far.pbrt): a camera beyond the
// scene's limits (1e12) loaded, and its first ray aborted Embree (`ray.valid()`). Refused at
// the Camera's line; so is a point light there (the light factory the Mitsuba loader shares).
TEST_F(PbrtTest, CameraAndLightsBeyondTheSceneLimitsAreRefused) {
    const std::string far_camera =
        "LookAt 3e38 0 0  0 0 0  0 1 0\nCamera \"perspective\"\nWorldBegin\n"
        "Shape \"sphere\"\n";
    const std::string message = error_of(far_camera);
    EXPECT_NE(message.find("scene.pbrt:2: the camera lies beyond 1e12"), std::string::npos)
        << message;
    EXPECT_NE(world_error("LightSource \"point\" \"point3 from\" [0 0 1e30]\n")
                  .find("within 1e12 of the origin"),
              std::string::npos);
}

}  // namespace
}  // namespace render
