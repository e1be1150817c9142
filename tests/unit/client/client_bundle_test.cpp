// The client's scene bundle (client/bundle.cpp) resolves files exactly as the loader does
// (core/scene/loader/file_resolver.h): the test scene of tests/data/mitsuba bundles to the files
// its README lists, a bundle copied to a fresh folder (as the server and the workers
// materialise a job) loads to the same scene, and <path> folders a job cannot carry are
// refused.

#include "client/bundle.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <set>
#include <string>

#include "core/base/error.h"
#include "core/scene/loader/scene_loader.h"

namespace render::service {
namespace {

namespace fs = std::filesystem;

std::set<std::string> paths_of(const SceneBundleInfo& info) {
    std::set<std::string> out;
    for (const BundleEntry& e : info.files) out.insert(e.path);
    return out;
}

struct TempDir {
    fs::path path;
    explicit TempDir(const std::string& name) {
        path = fs::temp_directory_path() / (name + "_" + std::to_string(::getpid()));
        fs::remove_all(path);
        fs::create_directories(path);
    }
    ~TempDir() {
        std::error_code ec;
        fs::remove_all(path, ec);
    }
    void write(const std::string& name, const std::string& text) const {
        fs::create_directories((path / name).parent_path());
        std::ofstream(path / name, std::ios::binary) << text;
    }
};

TEST(ClientBundle, FollowsTheLoadersFileResolution) {
    const fs::path root = fs::path(RENDER_SOURCE_DIR) / "tests/data/mitsuba";
    const SceneBundleInfo info = collect_bundle(root / "scene.xml", {});
    EXPECT_EQ(info.scene_path, "scene.xml");
    EXPECT_EQ(paths_of(info),
              (std::set<std::string>{"scene.xml", "include/a.xml", "include/b.xml",
                                     "include/beside.obj", "assets/tri.obj", "meshes/quad.ply"}));
    // As the loader: the wrapped integrator names the algorithm.
    EXPECT_EQ(info.integrator, "volpath");

    // The job's folder holds only the bundled files; the scene loads there to the same shapes.
    TempDir job("client_bundle_test_job");
    for (const BundleEntry& e : info.files) {
        fs::create_directories((job.path / e.path).parent_path());
        fs::copy_file(e.absolute, job.path / e.path);
    }
    ::testing::internal::CaptureStderr();
    auto original = load_scene(root / "scene.xml");
    auto copy = load_scene(job.path / "scene.xml");
    ::testing::internal::GetCapturedStderr();
    ASSERT_EQ(copy->shapes().size(), original->shapes().size());
    for (size_t i = 0; i < copy->shapes().size(); ++i)
        EXPECT_EQ(copy->shapes()[i]->surface_area(), original->shapes()[i]->surface_area()) << i;
}

// A spectrum file (<spectrum filename>) travels with the scene.
TEST(ClientBundle, TakesSpectrumFiles) {
    TempDir dir("client_bundle_test_spd");
    dir.write("spectra/white.spd", "400 0.5\n700 0.5\n");
    dir.write("scene.xml",
              "<scene version=\"3.0.0\"><sensor type=\"perspective\"/>"
              "<shape type=\"rectangle\"><bsdf type=\"diffuse\">"
              "<spectrum name=\"reflectance\" filename=\"spectra/white.spd\"/>"
              "</bsdf></shape></scene>");
    EXPECT_EQ(paths_of(collect_bundle(dir.path / "scene.xml", {})),
              (std::set<std::string>{"scene.xml", "spectra/white.spd"}));
}

// A bitmap texture's file travels with the scene, and the job's copy loads with it.
TEST(ClientBundle, TakesTextureFiles) {
    const fs::path scene = fs::path(RENDER_SOURCE_DIR) / "scenes/tests/textures.xml";
    const SceneBundleInfo info = collect_bundle(scene, {});
    EXPECT_EQ(paths_of(info), (std::set<std::string>{"textures.xml", "textures/tiles.png"}));
    TempDir job("client_bundle_test_textures");
    for (const BundleEntry& e : info.files) {
        fs::create_directories((job.path / e.path).parent_path());
        fs::copy_file(e.absolute, job.path / e.path);
    }
    auto copy = load_scene(job.path / "textures.xml", {}, job.path);  // confined, as a worker
    ASSERT_EQ(copy->shapes().size(), 5u);
    EXPECT_TRUE(copy->shapes()[0]->bsdf->varies());  // the bitmap floor
}

TEST(ClientBundle, SearchPathsMustStayInTheScenesFolder) {
    TempDir dir("client_bundle_test_paths");
    dir.write("scene/scene.xml",
              "<scene version=\"3.0.0\"><path value=\"$p\"/><shape type=\"obj\"><string "
              "name=\"filename\" value=\"m.obj\"/></shape></scene>");
    dir.write("scene/assets/m.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
    dir.write("outside/m.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
    const fs::path scene = dir.path / "scene/scene.xml";
    EXPECT_EQ(paths_of(collect_bundle(scene, {{"p", "assets"}})),
              (std::set<std::string>{"scene.xml", "assets/m.obj"}));
    auto message = [&](const std::string& p) {
        try {
            collect_bundle(scene, {{"p", p}});
        } catch (const std::exception& e) {
            return std::string(e.what());
        }
        return std::string("(no error)");
    };
    EXPECT_NE(message("../outside").find("outside the scene's folder"), std::string::npos)
        << message("../outside");
    EXPECT_NE(message((dir.path / "scene/assets").string()).find("is absolute"), std::string::npos)
        << message((dir.path / "scene/assets").string());
    // Found nowhere: named at its first candidate, beside the scene.
    EXPECT_NE(message("nowhere").find((dir.path / "scene/m.obj").string() + " (referenced from"),
              std::string::npos)
        << message("nowhere");
}

}  // namespace
}  // namespace render::service

namespace render::service {
namespace {

// A pbrt-v4 scene bundles its Include/Import files and "string filename" files (not Film's
// output name); copied to a job folder, it loads there, confined to that folder.
TEST(ClientBundle, PbrtScenesCarryIncludedFilesAndMeshes) {
    const fs::path root = fs::path(RENDER_SOURCE_DIR) / "scenes/bitterli-pbrt/coffee";
    const SceneBundleInfo info = collect_bundle(root / "scene-v4.pbrt", {});
    EXPECT_EQ(info.files.size(), 21u);  // the scene and its 20 PLY meshes
    EXPECT_EQ(paths_of(info).count("models/Mesh004.ply"), 1u);
    EXPECT_EQ(info.integrator, "pbrt:path");  // pbrt's name, as the loader records it
    EXPECT_EQ(info.sample_count, 64u);

    TempDir dir("client_bundle_test_pbrt");
    dir.write("scene.pbrt",
              "Film \"rgb\" \"string filename\" \"out.exr\" \"integer xresolution\" 4 "
              "\"integer yresolution\" 4\nWorldBegin\nInclude \"inc/shapes.pbrt\"\n");
    dir.write("inc/shapes.pbrt", "Shape \"plymesh\" \"string filename\" \"m/tri.ply\"\n");
    dir.write("m/tri.ply",
              "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
              "property float z\nelement face 1\nproperty list uchar int vertex_indices\n"
              "end_header\n0 0 1\n1 0 1\n0 1 1\n3 0 1 2\n");
    const SceneBundleInfo small = collect_bundle(dir.path / "scene.pbrt", {});
    EXPECT_EQ(paths_of(small),
              (std::set<std::string>{"scene.pbrt", "inc/shapes.pbrt", "m/tri.ply"}));
    EXPECT_EQ(small.integrator, "pbrt:volpath");  // pbrt's default, as the loader names it
    TempDir job("client_bundle_test_pbrt_job");
    for (const BundleEntry& e : small.files) {
        fs::create_directories((job.path / e.path).parent_path());
        fs::copy_file(e.absolute, job.path / e.path);
    }
    auto scene = render::load_scene(job.path / "scene.pbrt", {}, job.path);
    EXPECT_EQ(scene->shapes().size(), 1u);
    // A file outside the job's folder is refused.
    dir.write("escape.pbrt", "WorldBegin\nShape \"plymesh\" \"string filename\" \"../x.ply\"\n");
    EXPECT_THROW(render::load_scene(dir.path / "escape.pbrt", {}, dir.path), render::SceneError);
    EXPECT_THROW(collect_bundle(dir.path / "escape.pbrt", {}), std::runtime_error);
}

}  // namespace
}  // namespace render::service
