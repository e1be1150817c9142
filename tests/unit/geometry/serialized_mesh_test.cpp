// Mitsuba's `serialized` meshes: files written here from the documented format (our own writer,
// zlib's compress2) read back exactly, in both versions and precisions, by shape_index; the
// `serialized` shape applies to_world, flip_normals and face_normals; every malformed file
// (each truncation, corrupt data, bad header, index or dictionary) is a SceneError.

#include <gtest/gtest.h>
#include <unistd.h>
#include <zlib.h>

#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "core/base/error.h"
#include "core/mesh_io/serialized_reader.h"
#include "core/scene/loader/scene_loader.h"
#include "core/shapes/triangle_mesh.h"

namespace render {
namespace {

namespace fs = std::filesystem;

template <typename T>
void put(std::string& out, T value) {  // little-endian host (the reader asserts it too)
    out.append(reinterpret_cast<const char*>(&value), sizeof(T));
}

// One mesh as the test writes it.
struct TestMesh {
    std::vector<float> positions, normals, uvs, colors;  // flat arrays
    std::vector<uint32_t> indices;
    std::string name = "thing";
    bool double_precision = false;
    bool face_normals = false;
};

TestMesh square() {
    TestMesh m;
    m.positions = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0.25f};
    m.normals = {0, 0, 1, 0, 0.6f, 0.8f, 0, 0, 1, 0, 0, -1};
    m.uvs = {0, 0, 1, 0, 1, 0.75f, 0.125f, 1};
    m.indices = {0, 1, 2, 0, 2, 3};
    return m;
}

// The uncompressed stream of one mesh (after the 4-byte header), as documented.
std::string payload(const TestMesh& m, uint16_t version) {
    std::string s;
    uint32_t flags = m.double_precision ? 0x2000 : 0x1000;
    if (!m.normals.empty()) flags |= 0x1;
    if (!m.uvs.empty()) flags |= 0x2;
    if (!m.colors.empty()) flags |= 0x8;
    if (m.face_normals) flags |= 0x10;
    put(s, flags);
    if (version == 4) s += m.name + '\0';
    put(s, uint64_t(m.positions.size() / 3));
    put(s, uint64_t(m.indices.size() / 3));
    for (const auto* array : {&m.positions, &m.normals, &m.uvs, &m.colors})
        for (float v : *array) m.double_precision ? put(s, double(v)) : put(s, v);
    for (uint32_t i : m.indices) put(s, i);
    return s;
}

std::string compress(const std::string& raw) {
    uLongf size = compressBound(uLong(raw.size()));
    std::string out(size, '\0');
    EXPECT_EQ(compress2(reinterpret_cast<Bytef*>(out.data()), &size,
                        reinterpret_cast<const Bytef*>(raw.data()), uLong(raw.size()), 9),
              Z_OK);
    out.resize(size);
    return out;
}

// A file of several meshes with the end-of-file dictionary.
std::string serialized_file(const std::vector<TestMesh>& meshes, uint16_t version = 4) {
    std::string file;
    std::vector<uint64_t> offsets;
    for (const TestMesh& m : meshes) {
        offsets.push_back(file.size());
        put(file, uint16_t(0x041C));
        put(file, version);
        file += compress(payload(m, version));
    }
    for (uint64_t o : offsets) version == 4 ? put(file, o) : put(file, uint32_t(o));
    put(file, uint32_t(meshes.size()));
    return file;
}

void expect_mesh(const SerializedMesh& got, const TestMesh& want) {
    ASSERT_EQ(got.data.positions.size() * 3, want.positions.size());
    for (size_t i = 0; i < got.data.positions.size(); ++i)
        for (int c = 0; c < 3; ++c) EXPECT_EQ(got.data.positions[i][c], want.positions[3 * i + c]);
    ASSERT_EQ(got.data.normals.size() * 3, want.normals.size());
    for (size_t i = 0; i < got.data.normals.size(); ++i)
        for (int c = 0; c < 3; ++c) EXPECT_EQ(got.data.normals[i][c], want.normals[3 * i + c]);
    ASSERT_EQ(got.data.uvs.size() * 2, want.uvs.size());
    for (size_t i = 0; i < got.data.uvs.size(); ++i) {
        EXPECT_EQ(got.data.uvs[i].x, want.uvs[2 * i]);
        EXPECT_EQ(got.data.uvs[i].y, want.uvs[2 * i + 1]);
    }
    EXPECT_EQ(got.data.indices, want.indices);
    EXPECT_EQ(got.face_normals, want.face_normals);
}

TEST(SerializedMesh, ReadsOneMeshExactly) {
    const TestMesh m = square();
    const SerializedMesh got = read_serialized_from_memory(serialized_file({m}), 0, "a");
    expect_mesh(got, m);
    EXPECT_EQ(got.name, "thing");
}

TEST(SerializedMesh, ReadsEveryMeshByIndexInBothVersionsAndPrecisions) {
    TestMesh a = square();
    TestMesh b;  // double precision, colours (dropped), no normals, face-normal flag
    b.positions = {0.1f, 0.2f, 0.3f, 4, 5, 6, -7, 8, 9.5f};
    b.colors = {1, 0, 0, 0, 1, 0, 0, 0, 1};
    b.uvs = {0.5f, 0.5f, 0, 1, 1, 0};
    b.indices = {2, 1, 0};
    b.double_precision = true;
    b.face_normals = true;
    b.name = "second";
    TestMesh c = square();
    c.normals.clear();
    c.uvs.clear();
    for (float& p : c.positions) p *= 3;
    for (uint16_t version : {uint16_t(3), uint16_t(4)}) {
        const std::string file = serialized_file({a, b, c}, version);
        expect_mesh(read_serialized_from_memory(file, 0, "f"), a);
        const SerializedMesh second = read_serialized_from_memory(file, 1, "f");
        expect_mesh(second, b);
        EXPECT_EQ(second.name, version == 4 ? "second" : "");
        expect_mesh(read_serialized_from_memory(file, 2, "f"), c);
        try {
            read_serialized_from_memory(file, 3, "f.serialized");
            ADD_FAILURE() << "shape_index 3 of 3 meshes was accepted";
        } catch (const SceneError& e) {
            EXPECT_NE(std::string(e.what()).find("shape_index 3 is out of range: the file holds 3"),
                      std::string::npos)
                << e.what();
        }
    }
}

// Every prefix of a file that cuts a mesh's data is a SceneError, and so is every corrupted
// byte of a mesh's compressed data (zlib's checksum is checked at the end of each mesh) but
// one that flips only unused padding bits of the last DEFLATE byte, which reads the same mesh:
// never a crash, a hang, another exception or a wrong mesh.
TEST(SerializedMesh, EveryTruncationAndCorruptionIsASceneError) {
    TestMesh b = square();
    b.name = "b";
    const std::string file = serialized_file({square(), b});
    const size_t first_end = serialized_file({square()}).size() - 8 - 4;  // mesh 0's bytes
    for (size_t cut = 0; cut < file.size(); ++cut) {
        const std::string prefix = file.substr(0, cut);
        if (cut < first_end)
            EXPECT_THROW(read_serialized_from_memory(prefix, 0, "cut"), SceneError) << cut;
        else
            expect_mesh(read_serialized_from_memory(prefix, 0, "cut"), square());
        EXPECT_THROW(read_serialized_from_memory(prefix, 1, "cut"), SceneError) << cut;
    }
    size_t refused = 0;
    for (size_t at = 4; at < first_end; ++at) {
        std::string bad = file;
        bad[at] = char(bad[at] ^ 0x5a);
        try {
            expect_mesh(read_serialized_from_memory(bad, 0, "bad"), square());
        } catch (const SceneError&) {
            ++refused;
        }
    }
    EXPECT_GE(refused + 1, first_end - 4);  // at most the one byte with padding bits
}

TEST(SerializedMesh, RefusesBadHeadersCountsAndIndices) {
    auto message = [](const std::string& bytes, size_t index = 0) -> std::string {
        try {
            read_serialized_from_memory(bytes, index, "m.serialized");
        } catch (const SceneError& e) {
            return e.what();
        }
        return "accepted";
    };
    const std::string good = serialized_file({square()});
    std::string magic = good;
    magic[0] = 0x1d;
    EXPECT_NE(message(magic).find("not a Mitsuba serialized mesh"), std::string::npos);
    std::string version = good;
    version[2] = 5;
    EXPECT_NE(message(version).find("version 5 is not supported"), std::string::npos);
    EXPECT_NE(message("\x1c\x04").find("too short"), std::string::npos);

    TestMesh out_of_range = square();
    out_of_range.indices[4] = 9;
    EXPECT_NE(message(serialized_file({out_of_range}))
                  .find("triangle 1: vertex index 9 out of "
                        "range (4 vertices)"),
              std::string::npos)
        << message(serialized_file({out_of_range}));

    // Counts far beyond what the compressed bytes can hold are refused before allocating.
    std::string raw;
    put(raw, uint32_t(0x1000));
    raw += std::string("big") + '\0';
    put(raw, uint64_t(4000000000ull));
    put(raw, uint64_t(1) << 39);
    std::string huge;
    put(huge, uint16_t(0x041C));
    put(huge, uint16_t(4));
    huge += compress(raw);
    EXPECT_NE(message(huge).find("truncated or corrupt"), std::string::npos) << message(huge);
    std::string many = raw;
    std::memset(many.data() + 8, 0xff, 8);  // vertex count 2^64 - 1
    std::string many_file = huge.substr(0, 4) + compress(many);
    EXPECT_NE(message(many_file).find("more than 2^32 - 1"), std::string::npos);

    // An offset so large that offset + 4 overflows (found by the fuzzer: it read before the
    // file's start).
    std::string wrapped = serialized_file({square(), square()});
    std::memset(wrapped.data() + wrapped.size() - 4 - 8, 0xff, 8);
    EXPECT_NE(message(wrapped, 1).find("broken dictionary"), std::string::npos)
        << message(wrapped, 1);

    // A dictionary whose offset points elsewhere than a mesh header.
    std::string broken = serialized_file({square(), square()});
    broken[broken.size() - 4 - 8] = 3;  // mesh 1 "starts" at byte 3
    EXPECT_NE(message(broken, 1).find("broken dictionary"), std::string::npos)
        << message(broken, 1);
}

class SerializedShapeTest : public ::testing::Test {
  protected:
    void SetUp() override {
        dir_ = fs::temp_directory_path() /
               ("serialized_test_" + std::to_string(::getpid()) + "_" +
                ::testing::UnitTest::GetInstance()->current_test_info()->name());
        fs::create_directories(dir_);
        TestMesh flat = square();
        flat.face_normals = true;
        std::ofstream(dir_ / "meshes.serialized", std::ios::binary)
            << serialized_file({square(), flat});
    }
    void TearDown() override { fs::remove_all(dir_); }

    std::unique_ptr<Scene> load(const std::string& shapes) {
        const std::string xml =
            "<scene version=\"3.0.0\">\n"
            "<sensor type=\"perspective\"><float name=\"fov\" value=\"40\"/></sensor>\n" +
            shapes + "</scene>\n";
        std::ofstream(dir_ / "scene.xml") << xml;
        return load_scene(dir_ / "scene.xml");
    }
    std::string load_error(const std::string& shapes) {
        try {
            load(shapes);
        } catch (const SceneError& e) {
            return e.what();
        }
        return "loaded";
    }

    fs::path dir_;
};

TEST_F(SerializedShapeTest, AppliesToWorldFlipNormalsAndShapeIndex) {
    auto scene = load(
        "<shape type=\"serialized\">\n"
        "  <string name=\"filename\" value=\"meshes.serialized\"/>\n"
        "  <transform name=\"to_world\"><scale value=\"2\"/><translate x=\"1\"/></transform>\n"
        "  <boolean name=\"flip_normals\" value=\"true\"/>\n"
        "</shape>\n"
        "<shape type=\"serialized\">\n"
        "  <string name=\"filename\" value=\"meshes.serialized\"/>\n"
        "  <integer name=\"shape_index\" value=\"1\"/>\n"
        "</shape>\n");
    ASSERT_EQ(scene->shapes().size(), 2u);
    const auto* mesh = dynamic_cast<const TriangleMesh*>(scene->shapes()[0].get());
    ASSERT_NE(mesh, nullptr);
    const TestMesh want = square();
    for (size_t i = 0; i < 4; ++i)
        for (int c = 0; c < 3; ++c)
            EXPECT_EQ(mesh->positions()[i][c], want.positions[3 * i + c] * 2 + (c == 0 ? 1 : 0));

    // A ray down onto the first triangle (vertices 0, 1, 2; its normals (0,0,1), (0,.6,.8),
    // (0,0,1)) at barycentrics (b0, b1, b2) = (0.25, 0.5, 0.25) of the scaled square.
    SurfaceInteraction si;
    const Vec3 target = Vec3(1, 0, 0) + Vec3(2, 0, 0) * 0.5f + Vec3(2, 2, 0) * 0.25f;
    ASSERT_TRUE(
        scene->intersect(Ray(target + Vec3(0, 0, 5), Vec3(0, 0, -1)), si, HitDetail::kWithUv));
    EXPECT_NEAR(si.p.x, target.x, 1e-5f);
    EXPECT_NEAR(si.p.y, target.y, 1e-5f);
    const Vec3 n =
        normalize(Vec3(0, 0, 1) * 0.25f + Vec3(0, 0.6f, 0.8f) * 0.5f + Vec3(0, 0, 1) * 0.25f);
    EXPECT_NEAR(si.shading.n.y, -n.y, 1e-5f);  // flipped
    EXPECT_NEAR(si.shading.n.z, -n.z, 1e-5f);
    EXPECT_NEAR(si.geometric_normal.z, -1.0f, 1e-6f);
    EXPECT_NEAR(si.uv.x, 0.5f * 1 + 0.25f * 1, 1e-6f);  // uv as stored: not flipped
    EXPECT_NEAR(si.uv.y, 0.25f * 0.75f, 1e-6f);

    // Mesh 1 has the face-normal flag: flat shading despite its vertex normals.
    ASSERT_TRUE(scene->intersect(Ray(Vec3(0.75f, 0.25f, 5), Vec3(0, 0, -1)), si));
    EXPECT_EQ(si.shading.n.z, si.geometric_normal.z);
    EXPECT_EQ(si.shading.n.y, 0.0f);
}

TEST_F(SerializedShapeTest, ErrorsNameTheLineAndTheFile) {
    const std::string range = load_error(
        "<shape type=\"serialized\">\n"
        "  <string name=\"filename\" value=\"meshes.serialized\"/>\n"
        "  <integer name=\"shape_index\" value=\"2\"/>\n"
        "</shape>\n");
    EXPECT_NE(range.find("scene.xml:4"), std::string::npos) << range;  // the filename's line
    EXPECT_NE(range.find("meshes.serialized"), std::string::npos) << range;
    EXPECT_NE(range.find("shape_index 2 is out of range"), std::string::npos) << range;
    const std::string negative = load_error(
        "<shape type=\"serialized\">\n"
        "  <string name=\"filename\" value=\"meshes.serialized\"/>\n"
        "  <integer name=\"shape_index\" value=\"-1\"/>\n"
        "</shape>\n");
    EXPECT_NE(negative.find("shape_index"), std::string::npos) << negative;
    std::ofstream(dir_ / "cut.serialized", std::ios::binary)
        << serialized_file({square()}).substr(0, 20);
    const std::string cut = load_error(
        "<shape type=\"serialized\">\n"
        "  <string name=\"filename\" value=\"cut.serialized\"/>\n"
        "</shape>\n");
    EXPECT_NE(cut.find("scene.xml:4"), std::string::npos) << cut;
    EXPECT_NE(cut.find("truncated"), std::string::npos) << cut;
}

}  // namespace
}  // namespace render
