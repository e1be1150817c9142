// PLY and OBJ readers: round trips through small files in every encoding, polygon
// triangulation, index forms, and the error messages for malformed files.

#include <gtest/gtest.h>

#include <unistd.h>
#include <bit>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>

#include "core/base/error.h"
#include "core/mesh_io/obj_reader.h"
#include "core/mesh_io/ply_reader.h"

namespace render {
namespace {

namespace fs = std::filesystem;

class MeshIoTest : public ::testing::Test {
  protected:
    void SetUp() override {
        dir_ = fs::temp_directory_path() /
               ("mesh_io_test_" + std::to_string(::getpid()) + "_" +
                ::testing::UnitTest::GetInstance()->current_test_info()->name());
        fs::create_directories(dir_);
    }
    void TearDown() override { fs::remove_all(dir_); }

    fs::path write(const std::string& name, const std::string& bytes) {
        fs::path p = dir_ / name;
        std::ofstream(p, std::ios::binary) << bytes;
        return p;
    }

    fs::path dir_;
};

// Appends a value in the requested byte order.
template <typename T>
void put(std::string& out, T value, bool big_endian) {
    unsigned char b[sizeof(T)];
    std::memcpy(b, &value, sizeof(T));
    if (big_endian != (std::endian::native == std::endian::big))
        for (size_t i = 0; i < sizeof(T) / 2; ++i) std::swap(b[i], b[sizeof(T) - 1 - i]);
    out.append(reinterpret_cast<const char*>(b), sizeof(T));
}

// A square (quad) and a triangle; vertex normals all +z; uvs = (x, y).
const float kPositions[5][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {2, 0, 0}};

std::string binary_ply(bool big_endian) {
    std::string s = std::string("ply\nformat ") +
                    (big_endian ? "binary_big_endian" : "binary_little_endian") +
                    " 1.0\n"
                    "comment written by mesh_io_test\n"
                    "element vertex 5\n"
                    "property float x\nproperty float y\nproperty float z\n"
                    "property float nx\nproperty float ny\nproperty float nz\n"
                    "property double s\nproperty double t\n"
                    "property uchar red\n"
                    "element face 2\n"
                    "property list uchar uint vertex_indices\n"
                    "property int flags\n"
                    "element edge 1\n"
                    "property list ushort short vertex_pair\n"
                    "end_header\n";
    for (const auto& p : kPositions) {
        for (float c : p) put<float>(s, c, big_endian);
        put<float>(s, 0, big_endian), put<float>(s, 0, big_endian), put<float>(s, 1, big_endian);
        put<double>(s, p[0], big_endian), put<double>(s, p[1], big_endian);
        put<uint8_t>(s, 255, big_endian);
    }
    put<uint8_t>(s, 4, big_endian);
    for (uint32_t i : {0u, 1u, 2u, 3u}) put<uint32_t>(s, i, big_endian);
    put<int32_t>(s, 7, big_endian);
    put<uint8_t>(s, 3, big_endian);
    for (uint32_t i : {1u, 4u, 2u}) put<uint32_t>(s, i, big_endian);
    put<int32_t>(s, 7, big_endian);
    put<uint16_t>(s, 2, big_endian);
    put<int16_t>(s, 0, big_endian), put<int16_t>(s, 4, big_endian);
    return s;
}

void expect_square_and_triangle(const MeshData& m) {
    ASSERT_EQ(m.positions.size(), 5u);
    for (int i = 0; i < 5; ++i)
        EXPECT_EQ(m.positions[size_t(i)],
                  Vec3(kPositions[i][0], kPositions[i][1], kPositions[i][2]));
    ASSERT_EQ(m.normals.size(), 5u);
    EXPECT_EQ(m.normals[3], Vec3(0, 0, 1));
    ASSERT_EQ(m.uvs.size(), 5u);
    EXPECT_EQ(m.uvs[2].x, 1.0f);
    EXPECT_EQ(m.uvs[2].y, 1.0f);
    // The quad is fan-triangulated: (0 1 2) (0 2 3), then the triangle (1 4 2).
    std::vector<uint32_t> expected = {0, 1, 2, 0, 2, 3, 1, 4, 2};
    EXPECT_EQ(m.indices, expected);
}

TEST_F(MeshIoTest, PlyBinaryLittleEndian) {
    expect_square_and_triangle(read_ply(write("le.ply", binary_ply(false))));
}

TEST_F(MeshIoTest, PlyBinaryBigEndian) {
    expect_square_and_triangle(read_ply(write("be.ply", binary_ply(true))));
}

TEST_F(MeshIoTest, PlyAscii) {
    std::string s =
        "ply\r\nformat ascii 1.0\r\n"
        "element vertex 5\n"
        "property float32 x\nproperty float32 y\nproperty float32 z\n"
        "property float nx\nproperty float ny\nproperty float nz\n"
        "property float u\nproperty float v\n"
        "element face 2\n"
        "property list uint8 int32 vertex_index\n"
        "end_header\n"
        "0 0 0 0 0 1 0 0\n"
        "1 0 0 0 0 1 1 0\n"
        "1 1 0 0 0 1 1 1\n"
        "0 1 0 0 0 1 0 1\n"
        "2 0 0 0 0 1 2 0\n"
        "4 0 1 2 3\n"
        "3 1 4 2\n";
    expect_square_and_triangle(read_ply(write("a.ply", s)));
}

TEST_F(MeshIoTest, PlyPolygonIsFanTriangulated) {
    std::string s =
        "ply\nformat ascii 1.0\nelement vertex 5\nproperty float x\nproperty float y\n"
        "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
        "0 0 0\n1 0 0\n2 1 0\n1 2 0\n0 1 0\n"
        "5 0 1 2 3 4\n";
    MeshData m = read_ply(write("p.ply", s));
    std::vector<uint32_t> expected = {0, 1, 2, 0, 2, 3, 0, 3, 4};
    EXPECT_EQ(m.indices, expected);
    EXPECT_TRUE(m.normals.empty());
    EXPECT_TRUE(m.uvs.empty());
    // An element without properties is skipped whatever its count says.
    std::string junk = s;
    junk.replace(junk.find("end_header"), 10, "element junk 1000000000000\nend_header");
    EXPECT_EQ(read_ply(write("junk.ply", junk)).indices, expected);
}

std::string ply_error(const fs::path& p) {
    try {
        read_ply(p);
    } catch (const SceneError& e) {
        return e.what();
    }
    ADD_FAILURE() << "no error for " << p;
    return "";
}

TEST_F(MeshIoTest, PlyErrors) {
    const std::string header =
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
        "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n";
    std::string e;

    e = ply_error(write("magic.ply", "plx\nformat ascii 1.0\nend_header\n"));
    EXPECT_NE(e.find("magic.ply:1: not a PLY file"), std::string::npos) << e;

    e = ply_error(write("format.ply", "ply\nformat binary_middle_endian 1.0\nend_header\n"));
    EXPECT_NE(e.find("format.ply:2: unknown format"), std::string::npos) << e;

    e = ply_error(write("noend.ply", "ply\nformat ascii 1.0\nelement vertex 3\n"));
    EXPECT_NE(e.find("no end_header"), std::string::npos) << e;

    e = ply_error(write("type.ply",
                        "ply\nformat ascii 1.0\nelement vertex 1\n"
                        "property quad x\nend_header\n"));
    EXPECT_NE(e.find("type.ply:4: unknown property type \"quad\""), std::string::npos) << e;

    e = ply_error(write("noxyz.ply",
                        "ply\nformat ascii 1.0\nelement vertex 1\n"
                        "property float x\nend_header\n1\n"));
    EXPECT_NE(e.find("x, y and z"), std::string::npos) << e;

    e = ply_error(write("range.ply", header + "0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n"));
    EXPECT_NE(e.find("range.ply:13: face 0: vertex index 3 out of range"), std::string::npos) << e;

    e = ply_error(write("two.ply", header + "0 0 0\n1 0 0\n0 1 0\n2 0 1\n"));
    EXPECT_NE(e.find("face 0: a face needs at least 3 vertices"), std::string::npos) << e;

    e = ply_error(write("word.ply", header + "0 0 0\n1 zero 0\n0 1 0\n3 0 1 2\n"));
    EXPECT_NE(e.find("word.ply:11: vertex 1: \"zero\" is not a number"), std::string::npos) << e;

    e = ply_error(write("nan.ply", header + "0 0 0\n1 nan 0\n0 1 0\n3 0 1 2\n"));
    EXPECT_NE(e.find("vertex 1: non-finite vertex position"), std::string::npos) << e;

    e = ply_error(write("short.ply", header + "0 0 0\n1 0 0\n0 1 0\n3 0 1\n"));
    EXPECT_NE(e.find("face 0: file is truncated"), std::string::npos) << e;

    // Binary files cut at every length give an error, never a crash.
    std::string full = binary_ply(false);
    size_t body = full.find("end_header\n") + 11;
    for (size_t len = body; len < full.size(); len += 3) {
        e = ply_error(write("cut.ply", full.substr(0, len)));
        EXPECT_NE(e.find("truncated"), std::string::npos) << len << ": " << e;
    }
    // A header that promises more than the file holds.
    std::string big = full;
    big.replace(big.find("element face 2"), 14, "element face 9");
    e = ply_error(write("big.ply", big));
    EXPECT_NE(e.find("big.ply: face 2:"), std::string::npos) << e;
    big = full;
    big.replace(big.find("element edge 1"), 14, "element edge 4000000000");
    e = ply_error(write("huge.ply", big));
    EXPECT_NE(e.find("huge.ply: edge 1: file is truncated"), std::string::npos) << e;
}

TEST_F(MeshIoTest, ObjIndexForms) {
    std::string s =
        "# comment\n"
        "mtllib x.mtl\no thing\ng group\ns off\nusemtl m\n"
        "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"
        "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n"
        "vn 0 0 1\n"
        "f 1/1/1 2/2/1 3/3/1 4/4/1\n"      // quad, v/vt/vn
        "f -4/-4/-1 -2/-2/-1 -1/-1/-1\n";  // negative indices: vertices 1 3 4
    MeshData m = read_obj(write("forms.obj", s));
    ASSERT_EQ(m.positions.size(), 4u);  // identical (v, vt, vn) triples are shared
    EXPECT_EQ(m.normals.size(), 4u);
    EXPECT_EQ(m.uvs.size(), 4u);
    std::vector<uint32_t> expected = {0, 1, 2, 0, 2, 3, 0, 2, 3};
    EXPECT_EQ(m.indices, expected);
    EXPECT_EQ(m.positions[3], Vec3(0, 1, 0));
    EXPECT_EQ(m.uvs[2].x, 1.0f);
    EXPECT_EQ(m.normals[1], Vec3(0, 0, 1));
}

TEST_F(MeshIoTest, ObjPartialAttributesAreDropped) {
    std::string s =
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nvn 0 0 1\nvt 0.5 0.5\n"
        "f 1//1 2//1 3//1\n"
        "f 2/1 4/1 3/1\n"  // no normals here: the mesh keeps none
        "f 1 2 4\n";       // plain positions
    MeshData m = read_obj(write("mixed.obj", s));
    EXPECT_TRUE(m.normals.empty());
    EXPECT_TRUE(m.uvs.empty());
    EXPECT_EQ(m.positions.size(), 4u);
    EXPECT_EQ(m.indices.size(), 9u);
}

TEST_F(MeshIoTest, ObjPolygonAndContinuation) {
    std::string s = "v 0 0 0\nv 1 0 0\nv 2 1 0\nv 1 2 0\nv 0 1 0\nf 1 2 3 \\\n 4 5\n";
    MeshData m = read_obj(write("poly.obj", s));
    std::vector<uint32_t> expected = {0, 1, 2, 0, 2, 3, 0, 3, 4};
    EXPECT_EQ(m.indices, expected);
}

std::string obj_error(const fs::path& p) {
    try {
        read_obj(p);
    } catch (const SceneError& e) {
        return e.what();
    }
    ADD_FAILURE() << "no error for " << p;
    return "";
}

TEST_F(MeshIoTest, ObjErrors) {
    std::string e;
    e = obj_error(write("zero.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n"));
    EXPECT_NE(e.find("zero.obj:4: face: position index 0"), std::string::npos) << e;
    e = obj_error(write("range.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n"));
    EXPECT_NE(e.find("range.obj:4: face: position index 4 out of range"), std::string::npos) << e;
    e = obj_error(write("neg.obj", "v 0 0 0\nv 1 0 0\nf -1 -2 -3\n"));
    EXPECT_NE(e.find("neg.obj:3: face: position index -3 out of range"), std::string::npos) << e;
    e = obj_error(write("num.obj", "v 0 0 0\nv 1 x 0\n"));
    EXPECT_NE(e.find("num.obj:2: v: \"x\" is not a number"), std::string::npos) << e;
    e = obj_error(write("inf.obj", "v 0 0 inf\n"));
    EXPECT_NE(e.find("inf.obj:1: v: \"inf\" is not finite"), std::string::npos) << e;
    e = obj_error(write("vn.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1//1 2//1 3//1\n"));
    EXPECT_NE(e.find("vn.obj:4: face: normal index 1 out of range"), std::string::npos) << e;
    e = obj_error(write("two.obj", "v 0 0 0\nv 1 0 0\nf 1 2\n"));
    EXPECT_NE(e.find("two.obj:3: a face needs at least 3 vertices"), std::string::npos) << e;
    e = obj_error(write("slash.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1/ 2/ 3/\n"));
    EXPECT_NE(e.find("slash.obj:4: face: bad vertex"), std::string::npos) << e;
    e = obj_error(dir_ / "missing.obj");
    EXPECT_NE(e.find("missing.obj: file not found"), std::string::npos) << e;
}

TEST(MeshIoShipped, VeachBidirPlysLoad) {
    fs::path models = fs::path(RENDER_SOURCE_DIR) / "scenes/bitterli/veach-bidir/models";
    int count = 0;
    for (const auto& entry : fs::directory_iterator(models)) {
        if (entry.path().extension() != ".ply") continue;
        MeshData m = read_ply(entry.path());
        EXPECT_FALSE(m.positions.empty()) << entry.path();
        EXPECT_GT(m.indices.size(), 0u) << entry.path();
        EXPECT_EQ(m.indices.size() % 3, 0u) << entry.path();
        for (uint32_t i : m.indices) ASSERT_LT(i, m.positions.size()) << entry.path();
        EXPECT_TRUE(m.normals.empty() || m.normals.size() == m.positions.size());
        EXPECT_EQ(m.uvs.size(), m.positions.size()) << entry.path();
        ++count;
    }
    EXPECT_EQ(count, 12);
    // Mesh001 carries normals, Mesh000 does not (the scene gives it face_normals).
    EXPECT_FALSE(read_ply(models / "Mesh001.ply").normals.empty());
    EXPECT_TRUE(read_ply(models / "Mesh000.ply").normals.empty());
}

}  // namespace
}  // namespace render
