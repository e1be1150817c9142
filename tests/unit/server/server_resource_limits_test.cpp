// Every size a client controls is bounded with a clear error before memory is committed
// (docs/guide/reliability.md, "Resource limits"): each limit is tried just past it
// (refused with a message naming the limit) and, where that is cheap, at it (accepted, or refused
// only for another reason such as the data that the header announces being absent).

#include <gtest/gtest.h>

#include <unistd.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>

#include "core/base/error.h"
#include "core/base/memory_budget.h"
#include "core/image/exr_io.h"
#include "core/image/image.h"
#include "core/media/vol_file.h"
#include "core/mesh_io/mesh_limits.h"
#include "core/mesh_io/obj_reader.h"
#include "core/mesh_io/ply_reader.h"
#include "core/render/job_limits.h"
#include "core/scene/loader/scene_loader.h"
#include "core/scene/pbrt/scene_loader.h"
#include "core/scene/scene.h"
#include "core/shapes/triangle_mesh.h"
#include "core/util/sha256.h"
#include "server/asset_store.h"
#include "server/validation.h"

namespace render {
namespace {

namespace fs = std::filesystem;

#define EXPECT_CONTAINS(haystack, needle) \
    EXPECT_NE(std::string(haystack).find(needle), std::string::npos) << (haystack)

// The message of the SceneError that `f` throws; fails the test if it throws none.
template <class F>
std::string scene_error(F&& f) {
    try {
        f();
    } catch (const SceneError& e) {
        return e.what();
    }
    ADD_FAILURE() << "no SceneError";
    return "";
}

class TempDir {
  public:
    TempDir() {
        dir_ = fs::temp_directory_path() /
               ("resource_limits_test_" + std::to_string(::getpid()) + "_" +
                ::testing::UnitTest::GetInstance()->current_test_info()->name());
        fs::create_directories(dir_);
    }
    ~TempDir() { fs::remove_all(dir_); }
    fs::path write(const std::string& name, const std::string& text) const {
        fs::path p = dir_ / name;
        std::ofstream(p, std::ios::binary) << text;
        return p;
    }
    const fs::path& path() const { return dir_; }

  private:
    fs::path dir_;
};

// ---------------------------------------------------------------------------------------------
// Request limits (server/validation.h, core/render/job_limits.h)

v1::SubmitJobRequest valid_request() {
    v1::SubmitJobRequest r;
    r.mutable_settings()->set_iterations(16);
    v1::BundleFile* f = r.mutable_bundle()->add_files();
    f->set_path("scene.xml");
    f->set_sha256(std::string(64, 'a'));
    f->set_size(100);
    r.mutable_bundle()->set_scene_path("scene.xml");
    return r;
}

TEST(RequestLimits, AValidRequestPasses) {
    EXPECT_TRUE(server::check_submit_request(valid_request()).ok());
}

TEST(RequestLimits, FilmSide) {
    v1::SubmitJobRequest r = valid_request();
    r.mutable_settings()->set_width(kMaxFilmResolution);
    r.mutable_settings()->set_height(kMaxFilmResolution);
    EXPECT_TRUE(server::check_submit_request(r).ok());
    r.mutable_settings()->set_width(kMaxFilmResolution + 1);
    grpc::Status s = server::check_submit_request(r);
    EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
    EXPECT_CONTAINS(s.error_message(), "exceeds 8192");
}

TEST(RequestLimits, IterationsPerFrame) {
    v1::SubmitJobRequest r = valid_request();
    r.mutable_settings()->set_iterations(kMaxIterations);
    EXPECT_TRUE(server::check_submit_request(r).ok());
    r.mutable_settings()->set_iterations(kMaxIterations + 1);
    EXPECT_CONTAINS(server::check_submit_request(r).error_message(), "out of range [1, 10000000]");
}

TEST(RequestLimits, IterationsTimesFrames) {
    v1::SubmitJobRequest r = valid_request();
    for (size_t i = 0; i < server::kMaxFrames; ++i) r.add_frames();
    r.mutable_settings()->set_iterations(kMaxJobIterations / server::kMaxFrames);
    EXPECT_TRUE(server::check_submit_request(r).ok());
    r.mutable_settings()->set_iterations(kMaxJobIterations / server::kMaxFrames + 1);
    grpc::Status s = server::check_submit_request(r);
    EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
    EXPECT_CONTAINS(s.error_message(), "settings.iterations x frames: 100001 x 1000");
    EXPECT_CONTAINS(s.error_message(), "kMaxJobIterations");
    // The same check serves the server once a scene's sample_count gave the iterations.
    EXPECT_EQ(check_job_iterations(kMaxJobIterations, 1), "");
    EXPECT_CONTAINS(check_job_iterations(kMaxJobIterations + 1, 1), "kMaxJobIterations");
    EXPECT_CONTAINS(check_job_iterations(UINT64_MAX, 3), "kMaxJobIterations");
}

TEST(RequestLimits, Frames) {
    v1::SubmitJobRequest r = valid_request();
    r.mutable_settings()->set_iterations(1);
    for (size_t i = 0; i < server::kMaxFrames; ++i) r.add_frames();
    EXPECT_TRUE(server::check_submit_request(r).ok());
    r.add_frames();
    EXPECT_CONTAINS(server::check_submit_request(r).error_message(), "1001 frames exceed 1000");
}

TEST(RequestLimits, NumberOfBundleFiles) {
    v1::SubmitJobRequest r = valid_request();
    for (size_t i = 1; i < server::kMaxBundleFiles; ++i) {
        v1::BundleFile* f = r.mutable_bundle()->add_files();
        f->set_path("f" + std::to_string(i));
        f->set_sha256(std::string(64, 'b'));
        f->set_size(1);
    }
    EXPECT_TRUE(server::check_submit_request(r).ok());
    v1::BundleFile* f = r.mutable_bundle()->add_files();
    f->set_path("one-too-many");
    f->set_sha256(std::string(64, 'b'));
    grpc::Status s = server::check_submit_request(r);
    EXPECT_EQ(s.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
    EXPECT_CONTAINS(s.error_message(), "more than 10000 files");
}

TEST(RequestLimits, AssetAndBundleSize) {
    v1::SubmitJobRequest r = valid_request();
    r.mutable_bundle()->mutable_files(0)->set_size(server::kMaxAssetSize);
    EXPECT_TRUE(server::check_submit_request(r).ok());
    r.mutable_bundle()->mutable_files(0)->set_size(server::kMaxAssetSize + 1);
    grpc::Status s = server::check_submit_request(r);
    EXPECT_EQ(s.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
    EXPECT_CONTAINS(s.error_message(), "size limit");

    // Four assets of the largest size fill the bundle; one byte more is refused.
    r = valid_request();
    r.mutable_bundle()->mutable_files(0)->set_size(server::kMaxAssetSize);
    for (int i = 0; i < 3; ++i) {
        v1::BundleFile* f = r.mutable_bundle()->add_files();
        f->set_path("big" + std::to_string(i));
        f->set_sha256(std::string(64, 'c'));
        f->set_size(server::kMaxAssetSize);
    }
    EXPECT_TRUE(server::check_submit_request(r).ok());
    v1::BundleFile* f = r.mutable_bundle()->add_files();
    f->set_path("one-byte");
    f->set_sha256(std::string(64, 'd'));
    f->set_size(1);
    EXPECT_EQ(server::check_submit_request(r).error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
}

TEST(RequestLimits, PerJobAssetsLimitOfTheServer) {
    // server --max-job-assets 1000: a bundle of 1000 bytes in all is accepted, 1001 refused.
    v1::SubmitJobRequest r = valid_request();
    r.mutable_bundle()->mutable_files(0)->set_size(600);
    v1::BundleFile* f = r.mutable_bundle()->add_files();
    f->set_path("mesh.ply");
    f->set_sha256(std::string(64, 'e'));
    f->set_size(400);
    EXPECT_TRUE(server::check_submit_request(r, 1000).ok());
    f->set_size(401);
    grpc::Status s = server::check_submit_request(r, 1000);
    EXPECT_EQ(s.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
    EXPECT_CONTAINS(s.error_message(),
                    "bundle.files total more than 1000 bytes, the per-job size limit (server "
                    "--max-job-assets 1000 B)");
    // The server's limit never goes above the protocol's.
    r = valid_request();
    r.mutable_bundle()->mutable_files(0)->set_size(server::kMaxAssetSize);
    EXPECT_TRUE(server::check_submit_request(r, UINT64_MAX).ok());
}

// The asset store's total size limit (server --max-store-size): uploads reserve their declared
// size before writing; the stored assets, those being uploaded and those already in the store
// when it opens count.
TEST(AssetStoreLimits, StoreSizeJustPastTheLimit) {
    TempDir dir;
    const fs::path store_dir = dir.write("unused", "").parent_path() / "store";
    auto upload = [](server::AssetStore& store, const std::string& data) {
        server::AssetStore::Upload u(store, sha256_hex(data), data.size());
        if (std::string e = u.reserve(); !e.empty()) return e;
        EXPECT_EQ(u.write(data), "");
        EXPECT_EQ(u.commit(), "");
        return std::string();
    };
    {
        server::AssetStore store(store_dir, 10);
        EXPECT_EQ(upload(store, "123456"), "");
        EXPECT_EQ(store.stored_bytes(), 6u);
        // The same asset again replaces itself: it counts once.
        EXPECT_EQ(upload(store, "123456"), "");
        EXPECT_EQ(store.stored_bytes(), 6u);
        // 6 + 5 > 10: refused before anything is written; 6 + 4 = 10 fits.
        const std::string refused = upload(store, "abcde");
        EXPECT_CONTAINS(refused, "the asset store is full: an asset of 5 B (5 bytes) does not fit");
        EXPECT_CONTAINS(refused, "within the store's limit of 10 B (server --max-store-size)");
        EXPECT_EQ(store.reserved_bytes(), 0u);
        EXPECT_FALSE(store.has(sha256_hex("abcde")));
        EXPECT_EQ(upload(store, "abcd"), "");
        EXPECT_EQ(store.stored_bytes(), 10u);
    }
    {
        // Reopened: the 10 stored bytes count; not even 1 byte more fits.
        server::AssetStore store(store_dir, 10);
        EXPECT_EQ(store.stored_bytes(), 10u);
        EXPECT_CONTAINS(upload(store, "x"), "10 B stored");
    }
    {
        // Uploads in progress hold their reservation until they commit or fail.
        server::AssetStore store(store_dir, 16);
        server::AssetStore::Upload a(store, sha256_hex("abc"), 3);
        EXPECT_EQ(a.reserve(), "");
        EXPECT_EQ(store.reserved_bytes(), 3u);
        server::AssetStore::Upload b(store, sha256_hex("wxyz"), 4);
        EXPECT_CONTAINS(b.reserve(), "3 B being uploaded");
        {
            server::AssetStore::Upload c(store, sha256_hex("xyz"), 3);
            EXPECT_EQ(c.reserve(), "");  // 10 + 3 + 3 = 16
        }                                // abandoned: its reservation is released
        EXPECT_EQ(store.reserved_bytes(), 3u);
        EXPECT_EQ(a.write("abc"), "");
        EXPECT_EQ(a.commit(), "");
        EXPECT_EQ(store.reserved_bytes(), 0u);
        EXPECT_EQ(store.stored_bytes(), 13u);
    }
}

TEST(RequestLimits, Defines) {
    v1::SubmitJobRequest r = valid_request();
    auto& defines = *r.mutable_settings()->mutable_defines();
    for (int i = 0; i < 1000; ++i) defines["d" + std::to_string(i)] = "1";
    defines["d0"] = std::string(65536, 'v');
    EXPECT_TRUE(server::check_submit_request(r).ok());
    defines["d0"] = std::string(65537, 'v');
    EXPECT_CONTAINS(server::check_submit_request(r).error_message(), "is too long");
    defines["d0"] = "1";
    defines["one-more"] = "1";
    EXPECT_CONTAINS(server::check_submit_request(r).error_message(), "more than 1000 defines");
}

TEST(RequestLimits, PathLength) {
    EXPECT_EQ(server::check_bundle_path(std::string(server::kMaxPathLength, 'a')), "");
    EXPECT_CONTAINS(server::check_bundle_path(std::string(server::kMaxPathLength + 1, 'a')),
                    "longer than 1024");
}

// ---------------------------------------------------------------------------------------------
// Scene-file limits

std::string nested_scene(int levels) {
    std::string open, close;
    for (int i = 0; i < levels; ++i) open += "<x>", close = "</x>" + close;
    return "<scene version=\"3.0.0\">" + open + close + "</scene>";
}

TEST(SceneLimits, XmlNesting) {
    TempDir dir;
    // 64 levels below <scene> pass the depth check and fail on the unknown tag.
    std::string at = scene_error([&] { load_scene_from_string(nested_scene(64), dir.path()); });
    EXPECT_EQ(at.find("nested too deeply"), std::string::npos) << at;
    EXPECT_CONTAINS(at, "unknown tag");
    std::string past = scene_error([&] { load_scene_from_string(nested_scene(65), dir.path()); });
    EXPECT_CONTAINS(past, "elements are nested too deeply (more than 64 levels)");
}

// A chain of `n` files, each including the next; the last one is empty.
void write_include_chain(const TempDir& dir, int n, bool pbrt) {
    for (int i = 0; i < n; ++i) {
        const std::string next = "c" + std::to_string(i + 1) + (pbrt ? ".pbrt" : ".xml");
        const std::string body =
            pbrt ? (i + 1 < n ? "Include \"" + next + "\"\n" : "\n")
                 : "<scene version=\"3.0.0\">" +
                       (i + 1 < n ? "<include filename=\"" + next + "\"/>" : std::string()) +
                       "</scene>";
        dir.write("c" + std::to_string(i) + (pbrt ? ".pbrt" : ".xml"), body);
    }
}

const std::string kCamera =
    "<sensor type=\"perspective\"><float name=\"fov\" value=\"45\"/></sensor>"
    "<shape type=\"sphere\"><emitter type=\"area\"><rgb name=\"radiance\" value=\"1\"/>"
    "</emitter></shape>";

TEST(SceneLimits, MitsubaIncludeDepth) {
    TempDir dir;
    write_include_chain(dir, 40, false);
    // The main scene includes c{40 - depth}: `depth` nested includes in all.
    auto load_depth = [&](int depth) {
        return load_scene_from_string("<scene version=\"3.0.0\">" + kCamera +
                                          "<include filename=\"c" + std::to_string(40 - depth) +
                                          ".xml\"/></scene>",
                                      dir.path());
    };
    // 32 files deep with the main scene: 31 nested includes.
    EXPECT_NO_THROW(load_depth(31));
    EXPECT_CONTAINS(scene_error([&] { load_depth(32); }), "includes are nested too deeply");
}

TEST(SceneLimits, PbrtIncludeDepth) {
    TempDir dir;
    write_include_chain(dir, 40, true);
    const std::string world =
        "Camera \"perspective\"\nWorldBegin\nAttributeBegin\nAreaLightSource \"diffuse\"\n"
        "Shape \"sphere\"\nAttributeEnd\n";
    auto load_depth = [&](int depth) {
        return pbrt::load_scene_from_string(
            world + "Include \"c" + std::to_string(40 - depth) + ".pbrt\"\n", dir.path());
    };
    EXPECT_NO_THROW(load_depth(32));
    EXPECT_CONTAINS(scene_error([&] { load_depth(33); }), "nested too deeply");
}

std::string ply_header(uint64_t vertices, uint64_t faces) {
    return "ply\nformat binary_little_endian 1.0\nelement vertex " + std::to_string(vertices) +
           "\nproperty float x\nproperty float y\nproperty float z\nelement face " +
           std::to_string(faces) + "\nproperty list uchar int vertex_indices\nend_header\n";
}

TEST(MeshLimits, PlyCountsAreCheckedBeforeAllocation) {
    // At the limits the header passes and the (absent) data is what is refused.
    std::string at = scene_error(
        [&] { read_ply_from_memory(ply_header(kMaxMeshVertices, kMaxMeshTriangles), "at.ply"); });
    EXPECT_EQ(at.find("kMaxMesh"), std::string::npos) << at;
    EXPECT_CONTAINS(at, "truncated");
    EXPECT_CONTAINS(
        scene_error([&] { read_ply_from_memory(ply_header(kMaxMeshVertices + 1, 1), "v.ply"); }),
        "v.ply: 268435457 vertices exceed the limit of 268435456 (kMaxMeshVertices)");
    EXPECT_CONTAINS(
        scene_error([&] { read_ply_from_memory(ply_header(3, kMaxMeshTriangles + 1), "f.ply"); }),
        "f.ply: 268435457 triangles exceed the limit of 268435456 (kMaxMeshTriangles)");
    // A count beyond 32 bits is refused the same way.
    EXPECT_CONTAINS(
        scene_error([&] { read_ply_from_memory(ply_header(uint64_t(1) << 40, 1), "big.ply"); }),
        "kMaxMeshVertices");
}

TEST(MeshLimits, CheckMeshCounts) {
    EXPECT_NO_THROW(check_mesh_counts("m", kMaxMeshVertices, kMaxMeshTriangles));
    EXPECT_THROW(check_mesh_counts("m", kMaxMeshVertices + 1, 0), SceneError);
    EXPECT_THROW(check_mesh_counts("m", 0, kMaxMeshTriangles + 1), SceneError);
}

std::string vol_header(int32_t x, int32_t y, int32_t z) {
    std::string h = "VOL";
    h.push_back(char(3));
    const int32_t ints[5] = {1, x, y, z, 1};
    h.append(reinterpret_cast<const char*>(ints), sizeof ints);
    const float box[6] = {0, 0, 0, 1, 1, 1};
    h.append(reinterpret_cast<const char*>(box), sizeof box);
    return h;
}

TEST(GridLimits, VolValuesAreCheckedAgainstTheLimitAndTheFile) {
    auto parse = [](const std::string& bytes) {
        return parse_vol(std::vector<unsigned char>(bytes.begin(), bytes.end()), "g.vol");
    };
    // 1024^3 = 2^30 values: at the limit, refused only because the values are not there.
    std::string at = scene_error([&] { parse(vol_header(1024, 1024, 1024)); });
    EXPECT_CONTAINS(at, "truncated");
    std::string past = scene_error([&] { parse(vol_header(1024, 1024, 1025)); });
    EXPECT_CONTAINS(past,
                    "g.vol: grid 1024 x 1024 x 1025 x 1 is too large (more than 2^30 values)");
}

TEST(SceneLimits, FilmSideInTheSceneFile) {
    TempDir dir;
    auto film = [&](int width) {
        return load_scene_from_string(
            "<scene version=\"3.0.0\"><sensor type=\"perspective\"><film type=\"hdrfilm\">"
            "<integer name=\"width\" value=\"" +
                std::to_string(width) +
                "\"/><integer name=\"height\" value=\"4\"/></film></sensor>"
                "<shape type=\"sphere\"><emitter type=\"area\"><rgb name=\"radiance\" "
                "value=\"1\"/></emitter></shape></scene>",
            dir.path());
    };
    EXPECT_NO_THROW(film(65536));  // the server then refuses films wider than kMaxFilmResolution
    EXPECT_CONTAINS(scene_error([&] { film(65537); }), "width");
}

// ---------------------------------------------------------------------------------------------
// The memory budget (core/base/memory_budget.h)

TEST(MemoryBudget, ChargesUpToTheLimitAndRefusesPastIt) {
    SceneMemoryBudget budget(1000, "test --max-memory");
    EXPECT_NO_THROW(charge_scene_memory(600, "a"));
    EXPECT_NO_THROW(charge_scene_memory(400, "b"));  // exactly at the limit
    EXPECT_EQ(budget.charged(), 1000u);
    try {
        charge_scene_memory(1, "the last byte");
        ADD_FAILURE() << "no MemoryLimitExceeded";
    } catch (const MemoryLimitExceeded& e) {
        EXPECT_STREQ(e.what(),
                     "the last byte: the scene needs at least 1001 B of memory, more than the "
                     "1000 B limit (test --max-memory)");
        EXPECT_EQ(e.needed(), 1001u);
        EXPECT_EQ(e.limit(), 1000u);
    }
}

// A mesh over the budget reaches the loader's caller as a MemoryLimitExceeded with its numbers,
// though the shape factory adds the element's line to the message: the worker reports it as a
// refusal for memory, which the server does not count against the job (docs/guide/service.md).
TEST(MemoryBudget, AMeshOverTheBudgetStaysAMemoryRefusalThroughTheLoader) {
    TempDir dir;
    dir.write("m.ply", ply_header(3, 1) + std::string(3 * 12, '\0') + std::string(1, char(3)) +
                           std::string(12, '\0'));
    const std::string scene =
        "<scene version=\"3.0.0\"><shape type=\"ply\"><string name=\"filename\" "
        "value=\"m.ply\"/></shape></scene>";
    SceneMemoryBudget budget(16, "test --max-memory");
    try {
        load_scene_from_string(scene, dir.path());
        ADD_FAILURE() << "no MemoryLimitExceeded";
    } catch (const MemoryLimitExceeded& e) {
        EXPECT_CONTAINS(e.what(), "filename");
        EXPECT_CONTAINS(e.what(), "more than the 16 B limit (test --max-memory)");
        EXPECT_GT(e.needed(), 16u);
        EXPECT_EQ(e.limit(), 16u);
    }
}

TEST(MemoryBudget, WithoutABudgetChargesAreFree) {
    EXPECT_NO_THROW(charge_scene_memory(UINT64_MAX, "anything"));
    SceneMemoryBudget unlimited(0, "none");
    EXPECT_NO_THROW(charge_scene_memory(UINT64_MAX, "anything"));
    EXPECT_NO_THROW(charge_scene_memory(UINT64_MAX, "saturates, never wraps"));
    EXPECT_EQ(unlimited.charged(), UINT64_MAX);
}

TEST(MemoryBudget, TheInnermostBudgetIsCharged) {
    SceneMemoryBudget outer(100, "outer");
    {
        SceneMemoryBudget inner(10, "inner");
        EXPECT_THROW(charge_scene_memory(50, "x"), MemoryLimitExceeded);
        EXPECT_EQ(outer.charged(), 0u);
    }
    charge_scene_memory(50, "x");
    EXPECT_EQ(outer.charged(), 50u);
}

TEST(MemoryBudget, Sizes) {
    EXPECT_EQ(parse_byte_size("512"), 512u);
    EXPECT_EQ(parse_byte_size("4K"), 4096u);
    EXPECT_EQ(parse_byte_size("3M"), 3u << 20);
    EXPECT_EQ(parse_byte_size("2GiB"), 2ull << 30);
    EXPECT_EQ(parse_byte_size("1t"), 1ull << 40);
    EXPECT_THROW(parse_byte_size(""), std::invalid_argument);
    EXPECT_THROW(parse_byte_size("G"), std::invalid_argument);
    EXPECT_THROW(parse_byte_size("1.5G"), std::invalid_argument);
    EXPECT_THROW(parse_byte_size("4X"), std::invalid_argument);
    EXPECT_THROW(parse_byte_size("99999999999T"), std::invalid_argument);
    EXPECT_EQ(format_bytes(512), "512 B");
    EXPECT_EQ(format_bytes(3u << 20), "3.0 MiB");
    EXPECT_EQ(film_memory_bytes(8192, 8192, 5), 8192ull * 8192 * 3 * 8 * 5);
    EXPECT_GT(available_memory_bytes(), 0u);  // Linux: /proc/meminfo
}

// A PLY of `vertices` vertices (a fan) and `faces` triangles, binary.
std::string ply_fan(int vertices) {
    std::string s = ply_header(uint64_t(vertices), uint64_t(vertices - 2));
    for (int i = 0; i < vertices; ++i) {
        const float p[3] = {float(i), float(i * i % 7), 0.0f};
        s.append(reinterpret_cast<const char*>(p), sizeof p);
    }
    for (int i = 1; i + 1 < vertices; ++i) {
        s.push_back(char(3));
        const int32_t idx[3] = {0, i, i + 1};
        s.append(reinterpret_cast<const char*>(idx), sizeof idx);
    }
    return s;
}

TEST(MemoryBudget, PlyMeshIsChargedBeforeItIsAllocated) {
    const std::string ply = ply_fan(100);
    const uint64_t need = mesh_vertex_bytes(100, false, false) + mesh_triangle_bytes(98);
    {
        SceneMemoryBudget budget(need, "test");
        EXPECT_EQ(read_ply_from_memory(ply, "m.ply").indices.size(), 3u * 98);
        EXPECT_EQ(budget.charged(), need);
    }
    SceneMemoryBudget budget(need - 1, "test");
    EXPECT_CONTAINS(scene_error([&] { read_ply_from_memory(ply, "m.ply"); }),
                    "m.ply: faces: the scene needs at least");
}

TEST(MemoryBudget, ObjMeshIsCharged) {
    std::string obj;
    for (int i = 0; i < 50; ++i)
        obj += "v " + std::to_string(i) + " " + std::to_string(i % 3) + " 0\n";
    for (int i = 2; i < 50; ++i)
        obj += "f 1 " + std::to_string(i) + " " + std::to_string(i + 1) + "\n";
    uint64_t need = 0;
    {
        SceneMemoryBudget budget(0, "measure");
        read_obj_from_memory(obj, "m.obj");
        need = budget.charged();
    }
    // The corners while parsing (24 bytes each), the triangles and the vertices.
    EXPECT_GE(need, mesh_triangle_bytes(48) + mesh_vertex_bytes(50, false, false));
    {
        SceneMemoryBudget budget(need, "test");
        EXPECT_NO_THROW(read_obj_from_memory(obj, "m.obj"));
    }
    SceneMemoryBudget budget(need - 1, "test");
    EXPECT_CONTAINS(scene_error([&] { read_obj_from_memory(obj, "m.obj"); }), "m.obj");
}

TEST(MemoryBudget, GridAndImageAreCharged) {
    TempDir dir;
    VolumeGridData grid;
    grid.xres = grid.yres = grid.zres = 8;
    grid.channels = 1;
    grid.values.assign(512, 0.5f);
    grid.bbox.lo = Vec3(0, 0, 0);
    grid.bbox.hi = Vec3(1, 1, 1);
    const fs::path vol = dir.path() / "g.vol";
    write_vol_file(vol.string(), grid);
    {
        SceneMemoryBudget budget(8 * 512, "test");
        EXPECT_NO_THROW(read_vol_file(vol.string()));
    }
    {
        SceneMemoryBudget budget(8 * 512 - 1, "test");
        EXPECT_CONTAINS(scene_error([&] { read_vol_file(vol.string()); }), "g.vol: grid values");
    }

    Image image(64, 32);
    const fs::path exr = dir.path() / "i.exr";
    write_exr(exr, image, {}, {});
    {
        SceneMemoryBudget budget(64 * 32 * 3 * 4, "test");
        EXPECT_NO_THROW(read_image_file(exr));
    }
    SceneMemoryBudget budget(64 * 32 * 3 * 4 - 1, "test");
    EXPECT_CONTAINS(scene_error([&] { read_image_file(exr); }), "i.exr: 64 x 32 image");
}

TEST(MemoryBudget, PbrtInlineMeshIsCharged) {
    TempDir dir;
    const std::string scene =
        "Camera \"perspective\"\nWorldBegin\nAttributeBegin\nAreaLightSource \"diffuse\"\n"
        "Shape \"trianglemesh\" \"point3 P\" [0 0 0 1 0 0 0 1 0] \"integer indices\" [0 1 2]\n"
        "AttributeEnd\n";
    const uint64_t mesh = mesh_vertex_bytes(3, true, true) + mesh_triangle_bytes(1);
    {
        // The mesh, its triangle's hit record, and the shadow rays' BVH over its triangle
        // (charged by Scene::commit).
        SceneMemoryBudget budget(
            mesh + TriangleMesh::kHitRecordBytesPerTriangle + Scene::kShadowBvhBytesPerTriangle,
            "test");
        EXPECT_NO_THROW(pbrt::load_scene_from_string(scene, dir.path()));
    }
    SceneMemoryBudget budget(mesh - 1, "test");
    const std::string e = scene_error([&] { pbrt::load_scene_from_string(scene, dir.path()); });
    EXPECT_CONTAINS(e, "\"P\"");
    EXPECT_CONTAINS(e, "the mesh: the scene needs at least");
}

TEST(MemoryBudget, ASceneOverItsBudgetIsRefusedNamingTheFileAndTheLimit) {
    TempDir dir;
    dir.write("fan.ply", ply_fan(1000));
    const std::string xml = "<scene version=\"3.0.0\">" + kCamera +
                            "<shape type=\"ply\"><string name=\"filename\" value=\"fan.ply\"/>"
                            "</shape></scene>";
    {
        SceneMemoryBudget budget(1 << 20, "worker --max-memory 1.0 MiB");
        EXPECT_NO_THROW(load_scene_from_string(xml, dir.path()));
        EXPECT_GT(budget.charged(), mesh_triangle_bytes(998));
    }
    SceneMemoryBudget budget(64 << 10, "worker --max-memory 64.0 KiB");
    const std::string e = scene_error([&] { load_scene_from_string(xml, dir.path()); });
    EXPECT_CONTAINS(e, "fan.ply");
    EXPECT_CONTAINS(e, "more than the 64.0 KiB limit (worker --max-memory 64.0 KiB)");
}

}  // namespace
}  // namespace render
