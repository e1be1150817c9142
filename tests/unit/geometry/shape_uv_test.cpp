// The uv parametrisation of every shape, as Mitsuba 3 defines it, at known points: hits are
// traced through a loaded scene, so the loader's parameters (to_world, flip_normals,
// flip_tex_coords) are covered too. Expected values come from Mitsuba's definitions.

#include <gtest/gtest.h>

#include <unistd.h>
#include <filesystem>
#include <fstream>
#include <string>

#include "core/scene/loader/scene_loader.h"

namespace render {
namespace {

namespace fs = std::filesystem;

// Hit points are computed in float from a ray; 1e-5 covers that rounding (uv is O(1)).
constexpr float kTol = 1e-5f;

class ShapeUv : public ::testing::Test {
  protected:
    void SetUp() override {
        dir_ = fs::temp_directory_path() /
               ("shape_uv_test_" + std::to_string(::getpid()) + "_" +
                ::testing::UnitTest::GetInstance()->current_test_info()->name());
        fs::create_directories(dir_);
    }
    void TearDown() override {
        std::error_code ec;
        fs::remove_all(dir_, ec);
    }

    void load(const std::string& shapes) {
        scene_ = load_scene_from_string(
            "<scene version=\"3.0.0\"><sensor type=\"perspective\"><float name=\"fov\" "
            "value=\"45\"/></sensor>" +
                shapes + "</scene>",
            dir_);
    }

    // uv where the ray from `origin` along `direction` first hits the scene.
    Vec2 uv_of(const Vec3& origin, const Vec3& direction) {
        SurfaceInteraction si;
        EXPECT_TRUE(scene_->intersect(Ray(origin, normalize(direction)), si, HitDetail::kWithUv))
            << "no hit from " << origin;
        return si.uv;
    }

    fs::path dir_;
    std::unique_ptr<Scene> scene_;
};

#define EXPECT_UV(actual, u, v)                                           \
    do {                                                                  \
        const Vec2 a_ = (actual);                                         \
        EXPECT_NEAR(a_.x, u, kTol) << "(" << a_.x << ", " << a_.y << ")"; \
        EXPECT_NEAR(a_.y, v, kTol) << "(" << a_.x << ", " << a_.y << ")"; \
    } while (0)

TEST_F(ShapeUv, SphereIsLongitudeOverTwoPiAndColatitudeOverPi) {
    load("<shape type=\"sphere\"/>");
    // u = phi / 2pi with phi = atan2(y, x) in [0, 2pi), v = theta / pi with theta from +z.
    EXPECT_UV(uv_of(Vec3(3, 0, 0), Vec3(-1, 0, 0)), 0.0f, 0.5f);
    EXPECT_UV(uv_of(Vec3(0, 3, 0), Vec3(0, -1, 0)), 0.25f, 0.5f);
    EXPECT_UV(uv_of(Vec3(-3, 0, 0), Vec3(1, 0, 0)), 0.5f, 0.5f);
    EXPECT_UV(uv_of(Vec3(0, -3, 0), Vec3(0, 1, 0)), 0.75f, 0.5f);
    // theta = 45 degrees on the x-z plane.
    const float s = std::sqrt(0.5f);
    EXPECT_UV(uv_of(Vec3(3 * s, 0, 3 * s), Vec3(-1, 0, -1)), 0.0f, 0.25f);
    EXPECT_NEAR(uv_of(Vec3(0, 0, -3), Vec3(0, 0, 1)).y, 1.0f, kTol);
}

TEST_F(ShapeUv, SphereUvFollowsItsObjectSpaceAndIgnoresFlippedNormals) {
    // Centre, radius and a rotation of 90 degrees about z: the object's +x points along +y.
    load(R"(<shape type="sphere"><point name="center" value="1, 1, 1"/>
              <float name="radius" value="2"/><boolean name="flip_normals" value="true"/>
              <transform name="to_world"><rotate z="1" angle="90"/></transform></shape>)");
    // The centre is rotated too: (1, 1, 1) -> (-1, 1, 1).
    const Vec3 c(-1, 1, 1);
    EXPECT_UV(uv_of(c + Vec3(0, 5, 0), Vec3(0, -1, 0)), 0.0f, 0.5f);   // object +x
    EXPECT_UV(uv_of(c + Vec3(-5, 0, 0), Vec3(1, 0, 0)), 0.25f, 0.5f);  // object +y
    EXPECT_UV(uv_of(c + Vec3(5, 0, 0), Vec3(-1, 0, 0)), 0.75f, 0.5f);  // object -y
    EXPECT_NEAR(uv_of(c + Vec3(0, 0, 5), Vec3(0, 0, -1)).y, 0.0f, kTol);
}

TEST_F(ShapeUv, DiskIsRadiusAndAngle) {
    load(R"(<shape type="disk"><transform name="to_world"><scale value="2"/>
              <translate z="1"/></transform></shape>)");
    // Object-space radius r and phi / 2pi; the world disk has radius 2 at z = 1.
    EXPECT_UV(uv_of(Vec3(1, 0, 3), Vec3(0, 0, -1)), 0.5f, 0.0f);
    EXPECT_UV(uv_of(Vec3(0, 1, 3), Vec3(0, 0, -1)), 0.5f, 0.25f);
    EXPECT_UV(uv_of(Vec3(0, -1.5f, 3), Vec3(0, 0, -1)), 0.75f, 0.75f);
}

TEST_F(ShapeUv, RectangleMapsItsSquareOntoTheUnitSquare) {
    load(R"(<shape type="rectangle"><transform name="to_world"><scale x="2" y="4"/>
              <translate x="1"/></transform></shape>)");
    // Object (x, y) in [-1, 1]^2 -> ((x + 1) / 2, (y + 1) / 2).
    EXPECT_UV(uv_of(Vec3(2, -2, 1), Vec3(0, 0, -1)), 0.75f, 0.25f);  // object (0.5, -0.5)
    EXPECT_UV(uv_of(Vec3(-0.6f, 3.6f, 1), Vec3(0, 0, -1)), 0.1f, 0.95f);
}

TEST_F(ShapeUv, EveryCubeFaceMapsOntoTheUnitSquareAsMitsuba) {
    load("<shape type=\"cube\"/>");
    // Mitsuba's cube: per face, the corners that carry uv (0, 0), (1, 0) and (0, 1).
    struct Face {
        Vec3 normal, uv00, uv10, uv01;
    };
    const Face faces[] = {
        {{0, -1, 0}, {-1, -1, -1}, {-1, -1, 1}, {1, -1, -1}},
        {{0, 1, 0}, {1, 1, 1}, {-1, 1, 1}, {1, 1, -1}},
        {{1, 0, 0}, {1, -1, 1}, {1, 1, 1}, {1, -1, -1}},
        {{0, 0, 1}, {-1, -1, 1}, {-1, 1, 1}, {1, -1, 1}},
        {{-1, 0, 0}, {-1, -1, -1}, {-1, 1, -1}, {-1, -1, 1}},
        {{0, 0, -1}, {-1, 1, -1}, {-1, -1, -1}, {1, 1, -1}},
    };
    for (const Face& f : faces)
        for (const Vec2 st : {Vec2(0.3f, 0.8f), Vec2(0.9f, 0.1f)}) {
            const Vec3 p = f.uv00 + (f.uv10 - f.uv00) * st.x + (f.uv01 - f.uv00) * st.y;
            SCOPED_TRACE(::testing::Message() << "face " << f.normal);
            EXPECT_UV(uv_of(p + f.normal * 2.0f, -f.normal), st.x, st.y);
        }
}

TEST_F(ShapeUv, MeshFilesFlipVAsMitsubaUnlessAskedNot) {
    std::ofstream(dir_ / "quad.obj") << "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"
                                        "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n"
                                        "f 1/1 2/2 3/3 4/4\n";
    std::ofstream(dir_ / "quad.ply")
        << "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
           "property float z\nproperty float u\nproperty float v\nelement face 1\n"
           "property list uchar int vertex_indices\nend_header\n"
           "0 0 0 0 0\n1 0 0 1 0\n1 1 0 1 1\n0 1 0 0 1\n4 0 1 2 3\n";
    for (const char* type : {"obj", "ply"}) {
        SCOPED_TRACE(type);
        load(std::string("<shape type=\"") + type + "\"><string name=\"filename\" value=\"quad." +
             type + "\"/></shape>");
        // The file's (0.25, 0.75) is Mitsuba's (0.25, 1 - 0.75).
        EXPECT_UV(uv_of(Vec3(0.25f, 0.75f, 1), Vec3(0, 0, -1)), 0.25f, 0.25f);
        load(std::string("<shape type=\"") + type + "\"><string name=\"filename\" value=\"quad." +
             type + "\"/><boolean name=\"flip_tex_coords\" value=\"false\"/></shape>");
        EXPECT_UV(uv_of(Vec3(0.25f, 0.75f, 1), Vec3(0, 0, -1)), 0.25f, 0.75f);
    }
}

}  // namespace
}  // namespace render
