// Volume data: the .vol reader and writer (round trip, every kind of bad file), .vdb through
// OpenVDB, gridvolume's cell-centred trilinear interpolation against hand-computed values, the
// scene-file factory's errors, and the majorant grid: its DDA walks a ray's cells in order and
// its majorants bound the *interpolated* density everywhere (a bound that forgets the
// neighbouring voxels is caught).

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>
#include <string>
#include <vector>

#include "core/base/error.h"
#include "core/base/memory_budget.h"
#include "core/base/properties.h"
#include "core/media/constant_volume.h"
#include "core/media/grid_volume.h"
#include "core/media/majorant_grid.h"
#include "core/media/vdb_file.h"
#include "core/media/vol_file.h"
#include "core/media/volume_factory.h"
#include "core/sampling/rng.h"

namespace render {
namespace {

namespace fs = std::filesystem;

// A fresh directory for this test's files.
fs::path temp_dir() {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    fs::path dir = fs::temp_directory_path() / (std::string("render_volume_test_") +
                                                info->test_suite_name() + "_" + info->name());
    fs::remove_all(dir);
    fs::create_directories(dir);
    return dir;
}

VolumeGridData make_grid(int nx, int ny, int nz, int channels,
                         const std::function<float(int, int, int, int)>& f) {
    VolumeGridData d;
    d.xres = nx, d.yres = ny, d.zres = nz, d.channels = channels;
    d.bbox.lo = Vec3(0.0f);
    d.bbox.hi = Vec3(1.0f);
    for (int z = 0; z < nz; ++z)
        for (int y = 0; y < ny; ++y)
            for (int x = 0; x < nx; ++x)
                for (int c = 0; c < channels; ++c) d.values.push_back(f(x, y, z, c));
    return d;
}

VolumeGridData random_grid(int nx, int ny, int nz, int channels, uint64_t seed) {
    Rng rng(StreamKey{seed, 0, 1, 0});
    return make_grid(nx, ny, nz, channels, [&](int, int, int, int) {
        // Mostly small values with occasional spikes: a majorant that forgets a neighbour
        // shows.
        const float u = rng.next_1d();
        return u < 0.1f ? 10.0f * rng.next_1d() : rng.next_1d();
    });
}

std::vector<unsigned char> read_bytes(const fs::path& p) {
    std::ifstream f(p, std::ios::binary);
    return {std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>()};
}
void write_bytes(const fs::path& p, const std::vector<unsigned char>& bytes) {
    std::ofstream f(p, std::ios::binary | std::ios::trunc);
    f.write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
}

// Runs `f`, which must throw a SceneError whose message contains `needle`.
void expect_scene_error(const std::function<void()>& f, const std::string& needle) {
    try {
        f();
        ADD_FAILURE() << "no SceneError; expected one mentioning \"" << needle << "\"";
    } catch (const SceneError& e) {
        EXPECT_NE(std::string(e.what()).find(needle), std::string::npos)
            << "message \"" << e.what() << "\" does not mention \"" << needle << "\"";
    }
}

TEST(VolFile, RoundTrip) {
    const fs::path dir = temp_dir();
    for (int channels : {1, 3}) {
        VolumeGridData d = random_grid(5, 3, 4, channels, 7 + channels);
        d.bbox.lo = Vec3(-1.0f, 0.5f, 2.0f);
        d.bbox.hi = Vec3(3.0f, 1.5f, 2.25f);
        const fs::path p = dir / ("grid" + std::to_string(channels) + ".vol");
        write_vol_file(p.string(), d);
        EXPECT_EQ(fs::file_size(p), 48u + 4u * d.values.size());
        const VolumeGridData r = read_vol_file(p.string());
        EXPECT_EQ(r.xres, 5);
        EXPECT_EQ(r.yres, 3);
        EXPECT_EQ(r.zres, 4);
        EXPECT_EQ(r.channels, channels);
        EXPECT_EQ(r.bbox.lo, d.bbox.lo);
        EXPECT_EQ(r.bbox.hi, d.bbox.hi);
        EXPECT_EQ(r.values, d.values);
        // x fastest, channels interleaved (Mitsuba's layout): check the bytes of one value.
        const std::vector<unsigned char> bytes = read_bytes(p);
        const size_t index = ((size_t(2) * 3 + 1) * 5 + 3) * size_t(channels);  // (3, 1, 2)
        float v;
        std::memcpy(&v, &bytes[48 + 4 * index], 4);
        EXPECT_EQ(v, d.at(3, 1, 2, 0));
        EXPECT_EQ(bytes[0], 'V');
        EXPECT_EQ(bytes[3], 3);
    }
}

TEST(VolFile, BadFilesAreErrors) {
    const fs::path dir = temp_dir();
    const VolumeGridData d = random_grid(4, 4, 4, 1, 3);
    const fs::path good = dir / "good.vol";
    write_vol_file(good.string(), d);
    const std::vector<unsigned char> bytes = read_bytes(good);

    auto variant = [&](const std::string& name, std::vector<unsigned char> b) {
        const fs::path p = dir / name;
        write_bytes(p, b);
        return p.string();
    };
    auto set_i32 = [](std::vector<unsigned char> b, size_t at, int32_t v) {
        std::memcpy(&b[at], &v, 4);
        return b;
    };
    expect_scene_error([&] { read_vol_file((dir / "missing.vol").string()); }, "cannot open");
    expect_scene_error([&] { read_vol_file(variant("empty.vol", {})); },
                       "shorter than the 48-byte");
    expect_scene_error(
        [&] {
            read_vol_file(variant("short_header.vol", {bytes.begin(), bytes.begin() + 20}));
        },
        "shorter than the 48-byte");
    std::vector<unsigned char> b = bytes;
    b[2] = 'X';
    expect_scene_error([&] { read_vol_file(variant("magic.vol", b)); },
                       "does not start with \"VOL\"");
    b = bytes;
    b[3] = 2;
    expect_scene_error([&] { read_vol_file(variant("version.vol", b)); }, "version 2");
    expect_scene_error([&] { read_vol_file(variant("encoding.vol", set_i32(bytes, 4, 2))); },
                       "encoding 2");
    expect_scene_error([&] { read_vol_file(variant("zero.vol", set_i32(bytes, 12, 0))); },
                       "invalid grid size");
    expect_scene_error([&] { read_vol_file(variant("negative.vol", set_i32(bytes, 16, -4))); },
                       "invalid grid size");
    expect_scene_error([&] { read_vol_file(variant("channels.vol", set_i32(bytes, 20, 2))); },
                       "channel count 2");
    // Sizes that do not match the data: one byte short, one value short, trailing bytes, and a
    // header claiming an enormous grid (reported without allocating it).
    expect_scene_error(
        [&] {
            read_vol_file(variant("short1.vol", {bytes.begin(), bytes.end() - 1}));
        },
        "truncated");
    expect_scene_error(
        [&] {
            read_vol_file(variant("short4.vol", {bytes.begin(), bytes.end() - 4}));
        },
        "truncated");
    b = bytes;
    b.push_back(0);
    expect_scene_error([&] { read_vol_file(variant("long.vol", b)); }, "trailing data");
    expect_scene_error([&] { read_vol_file(variant("wrongsize.vol", set_i32(bytes, 8, 5))); },
                       "truncated");
    b = set_i32(set_i32(set_i32(bytes, 8, 1 << 30), 12, 1 << 30), 16, 1 << 30);
    expect_scene_error([&] { read_vol_file(variant("huge.vol", b)); }, "too large");

    // Values: NaN, infinite and negative densities name the voxel.
    for (auto [value, word] : {std::pair{std::nanf(""), "NaN"},
                               {-0.5f, "negative"},
                               {std::numeric_limits<float>::infinity(), "infinite"}}) {
        VolumeGridData bad = d;
        bad.values[1 + 4 * (2 + 4 * 3)] = value;  // voxel (1, 2, 3)
        expect_scene_error([&] { check_volume_values(bad, "bad.vol"); }, word);
        expect_scene_error([&] { check_volume_values(bad, "bad.vol"); }, "(1, 2, 3)");
    }
    EXPECT_NO_THROW(check_volume_values(d, "good.vol"));
}

// Every possible truncation and a sweep of single-byte corruptions of the header never crash:
// either a clean SceneError or a valid grid.
TEST(VolFile, NeverCrashesOnCorruptHeaders) {
    const fs::path dir = temp_dir();
    const VolumeGridData d = random_grid(3, 2, 2, 3, 5);
    const fs::path good = dir / "good.vol";
    write_vol_file(good.string(), d);
    const std::vector<unsigned char> bytes = read_bytes(good);
    for (size_t n = 0; n < bytes.size(); ++n)
        EXPECT_THROW(parse_vol({bytes.begin(), bytes.begin() + long(n)}, "t"), SceneError);
    for (size_t at = 0; at < 48; ++at)
        for (unsigned char v : {0x00, 0x01, 0x7f, 0x80, 0xff}) {
            std::vector<unsigned char> b = bytes;
            b[at] = v;
            try {
                const VolumeGridData r = parse_vol(b, "t");
                EXPECT_EQ(r.values.size(), r.voxel_count() * size_t(r.channels));
            } catch (const SceneError&) {
            }
        }
}

TEST(VdbFile, RoundTripAndAgreesWithVol) {
    const fs::path dir = temp_dir();
    VolumeGridData d = random_grid(6, 5, 4, 1, 11);
    d.values[0] = 0;  // zeros are kept as active voxels
    d.bbox.lo = Vec3(-1.0f, 0.0f, 2.0f);
    d.bbox.hi = Vec3(2.0f, 1.0f, 4.0f);
    const fs::path p = dir / "grid.vdb";
    write_vdb_file(p.string(), d);
    const VolumeGridData r = read_vdb_file(p.string());
    EXPECT_EQ(r.xres, 6);
    EXPECT_EQ(r.yres, 5);
    EXPECT_EQ(r.zres, 4);
    EXPECT_EQ(r.channels, 1);
    EXPECT_EQ(r.values, d.values);
    for (int a = 0; a < 3; ++a) {
        EXPECT_NEAR(r.bbox.lo[a], d.bbox.lo[a], 1e-5f);
        EXPECT_NEAR(r.bbox.hi[a], d.bbox.hi[a], 1e-5f);
    }

    expect_scene_error([&] { read_vdb_file((dir / "missing.vdb").string()); }, "missing.vdb");
    write_bytes(dir / "garbage.vdb", {'n', 'o', 't', ' ', 'v', 'd', 'b'});
    expect_scene_error([&] { read_vdb_file((dir / "garbage.vdb").string()); }, "garbage.vdb");
}

// The plugin's sink refuses a grid over the scene's memory budget before it is densified: the
// budget's own error comes back through the C interface (core/media/vdb_file.cpp).
TEST(VdbFile, GridOverTheMemoryBudgetIsRefusedBeforeDensifying) {
    const fs::path dir = temp_dir();
    VolumeGridData d = random_grid(6, 5, 4, 1, 12);
    d.bbox.lo = Vec3(0.0f);
    d.bbox.hi = Vec3(1.0f);
    const fs::path p = dir / "budget.vdb";
    write_vdb_file(p.string(), d);
    SceneMemoryBudget budget(4 * 6 * 5 * 4 - 1, "the test");  // one byte short of the grid
    try {
        read_vdb_file(p.string());
        ADD_FAILURE() << "read past the budget";
    } catch (const MemoryLimitExceeded& e) {
        EXPECT_NE(std::string(e.what()).find("budget.vdb: grid \"density\" densified"),
                  std::string::npos)
            << e.what();
    }
}

// Without the volume plugin (librender_volume_vdb.so, which links OpenVDB) a .vdb file is a
// SceneError naming the file, the plugin and where it was looked for; .vol files need no plugin.
TEST(VdbFile, MissingPluginIsASceneErrorNamingIt) {
    const fs::path dir = temp_dir();
    VolumeGridData d = random_grid(2, 2, 2, 1, 13);
    d.bbox.lo = Vec3(0.0f);
    d.bbox.hi = Vec3(1.0f);
    write_vol_file((dir / "ok.vol").string(), d);
    // Any bytes: without the plugin nothing parses the file.
    write_bytes(dir / "ok.vdb", {'n', 'o', 't', ' ', 'v', 'd', 'b'});
    // The plugin, once loaded, stays loaded for the process: the child must be a fresh one.
    GTEST_FLAG_SET(death_test_style, "threadsafe");
    EXPECT_EXIT(
        {
            setenv("RENDER_VOLUME_PLUGIN", "/nonexistent/librender_volume_vdb.so", 1);
            read_vol_file((dir / "ok.vol").string());
            try {
                read_vdb_file((dir / "ok.vdb").string());
            } catch (const SceneError& e) {
                std::cerr << e.what() << std::endl;
                std::exit(3);
            }
            std::exit(0);
        },
        testing::ExitedWithCode(3),
        "ok.vdb: the volume plugin librender_volume_vdb.so \\(OpenVDB\\), needed to read "
        ".*ok.vdb, cannot be loaded.*/nonexistent/librender_volume_vdb.so");
}

// Mitsuba 3's convention (grid_volume.h): cell-centred values, clamped at the faces.
TEST(GridVolume, TrilinearMatchesHandComputedValues) {
    // 2 x 2 x 2, v = x + 2y + 4z: voxel centres at 1/4 and 3/4.
    GridVolume cube(
        make_grid(2, 2, 2, 1, [](int x, int y, int z, int) { return float(x + 2 * y + 4 * z); }),
        Transform());
    EXPECT_EQ(cube.channels(), 1);
    EXPECT_FLOAT_EQ(cube.eval(Vec3(0.25f, 0.25f, 0.25f)).r, 0.0f);
    EXPECT_FLOAT_EQ(cube.eval(Vec3(0.75f, 0.75f, 0.75f)).g, 7.0f);
    EXPECT_FLOAT_EQ(cube.eval(Vec3(0.5f, 0.5f, 0.5f)).b, 3.5f);
    EXPECT_FLOAT_EQ(cube.eval(Vec3(0.5f, 0.25f, 0.25f)).r, 0.5f);
    // (0.375, 0.625, 0.5): x = 0.25, y = 0.75, z = 0.5 -> 0.25 + 2 * 0.75 + 4 * 0.5.
    EXPECT_FLOAT_EQ(cube.eval(Vec3(0.375f, 0.625f, 0.5f)).r, 3.75f);
    // Within half a voxel of a face the face voxel's value (clamp), not zero.
    EXPECT_FLOAT_EQ(cube.eval(Vec3(0.0f, 0.0f, 0.0f)).r, 0.0f);
    EXPECT_FLOAT_EQ(cube.eval(Vec3(1.0f, 1.0f, 1.0f)).r, 7.0f);
    EXPECT_FLOAT_EQ(cube.eval(Vec3(0.1f, 0.9f, 0.2f)).r, 2.0f);
    // Outside the unit cube: 0.
    EXPECT_EQ(cube.eval(Vec3(1.01f, 0.5f, 0.5f)), Rgb(0.0f));
    EXPECT_EQ(cube.eval(Vec3(0.5f, -0.01f, 0.5f)), Rgb(0.0f));
    EXPECT_EQ(cube.max_value(), 7.0f);

    // 3 x 1 x 1 with values 1, 3, 9 along x: centres at 1/6, 1/2, 5/6.
    const VolumeGridData line = make_grid(
        3, 1, 1, 1, [](int x, int, int, int) { return x == 0 ? 1.0f : (x == 1 ? 3.0f : 9.0f); });
    GridVolume tri(line, Transform());
    EXPECT_FLOAT_EQ(tri.eval(Vec3(0.5f, 0.3f, 0.9f)).r, 3.0f);
    EXPECT_FLOAT_EQ(tri.eval(Vec3(2.0f / 3.0f, 0.5f, 0.5f)).r, 6.0f);
    EXPECT_FLOAT_EQ(tri.eval(Vec3(1.0f / 3.0f, 0.5f, 0.5f)).r, 2.0f);
    EXPECT_FLOAT_EQ(tri.eval(Vec3(0.1f, 0.5f, 0.5f)).r, 1.0f);
    GridVolume nearest(line, Transform(), VolumeFilter::kNearest);
    EXPECT_FLOAT_EQ(nearest.eval(Vec3(0.6f, 0.5f, 0.5f)).r, 3.0f);
    EXPECT_FLOAT_EQ(nearest.eval(Vec3(0.7f, 0.5f, 0.5f)).r, 9.0f);
    EXPECT_FLOAT_EQ(nearest.eval(Vec3(1.0f, 0.5f, 0.5f)).r, 9.0f);

    // to_world places the unit cube: scale 2 then translate (1, 0, -1) -> [1,3] x [0,2] x [-1,1].
    GridVolume placed(line, Transform::translate(Vec3(1, 0, -1)) * Transform::scale(Vec3(2.0f)));
    EXPECT_FLOAT_EQ(placed.eval(Vec3(1.0f + 2.0f * 2.0f / 3.0f, 1.0f, 0.0f)).r, 6.0f);
    EXPECT_EQ(placed.eval(Vec3(0.9f, 1.0f, 0.0f)), Rgb(0.0f));
    EXPECT_EQ(placed.bounds().lo, Vec3(1, 0, -1));
    EXPECT_EQ(placed.bounds().hi, Vec3(3, 2, 1));

    // Three channels interpolate independently.
    GridVolume rgb(make_grid(2, 1, 1, 3, [](int x, int, int, int c) { return float(10 * c + x); }),
                   Transform());
    const Rgb v = rgb.eval(Vec3(0.5f, 0.5f, 0.5f));
    EXPECT_EQ(rgb.channels(), 3);
    EXPECT_FLOAT_EQ(v.r, 0.5f);
    EXPECT_FLOAT_EQ(v.g, 10.5f);
    EXPECT_FLOAT_EQ(v.b, 20.5f);
    EXPECT_FLOAT_EQ(rgb.max_value(), 21.0f);
}

Properties grid_props(const std::string& filename) {
    Properties p("volume", "gridvolume", SourceLocation{"scene.xml", 3});
    p.set("filename", filename, SourceLocation{"scene.xml", 4});
    return p;
}

TEST(VolumeFactory, BuildsVolumesAndReportsErrors) {
    const fs::path dir = temp_dir();
    write_vol_file((dir / "a.vol").string(),
                   make_grid(2, 2, 2, 1, [](int x, int, int, int) { return float(x); }));
    write_vdb_file((dir / "a.vdb").string(),
                   make_grid(2, 2, 2, 1, [](int x, int, int, int) { return float(x); }));

    // .vol and .vdb give the same volume; use_grid_bbox places it by the file's box.
    for (const char* name : {"a.vol", "a.vdb"}) {
        Properties p = grid_props(name);
        auto v = make_volume(p, dir.string());
        p.check_all_used();
        EXPECT_FLOAT_EQ(v->eval(Vec3(0.5f, 0.5f, 0.5f)).r, 0.5f) << name;
        EXPECT_EQ(v->bounds().hi, Vec3(1.0f));
    }
    {
        VolumeGridData boxed = make_grid(2, 1, 1, 1, [](int x, int, int, int) { return float(x); });
        boxed.bbox.lo = Vec3(10, 0, 0);
        boxed.bbox.hi = Vec3(14, 1, 1);
        write_vol_file((dir / "boxed.vol").string(), boxed);
        Properties p = grid_props("boxed.vol");
        p.set("use_grid_bbox", true, SourceLocation{"scene.xml", 5});
        auto v = make_volume(p, dir.string());
        EXPECT_FLOAT_EQ(v->eval(Vec3(12.0f, 0.5f, 0.5f)).r, 0.5f);
        EXPECT_EQ(v->bounds().lo, Vec3(10, 0, 0));
    }
    {
        Properties p("volume", "constvolume", SourceLocation{"scene.xml", 3});
        p.set("value", Rgb(0.5f, 1.0f, 2.0f), SourceLocation{"scene.xml", 4});
        auto v = make_volume(p, dir.string());
        EXPECT_EQ(v->eval(Vec3(1e6f, -3.0f, 0.0f)), Rgb(0.5f, 1.0f, 2.0f));
        EXPECT_EQ(v->channels(), 3);
        EXPECT_FALSE(is_bounded(v->bounds()));
    }

    expect_scene_error([&] { make_volume(grid_props("nothere.vol"), dir.string()); },
                       "scene.xml:4:");
    expect_scene_error([&] { make_volume(grid_props("nothere.vol"), dir.string()); },
                       "volume file not found");
    write_bytes(dir / "bad.vol", {'V', 'O', 'X', 3});
    expect_scene_error([&] { make_volume(grid_props("bad.vol"), dir.string()); }, "scene.xml:4:");
    VolumeGridData nan_grid = make_grid(2, 2, 2, 1, [](int, int, int, int) { return 1.0f; });
    nan_grid.values[5] = std::nanf("");
    write_vol_file((dir / "nan.vol").string(), nan_grid);
    expect_scene_error([&] { make_volume(grid_props("nan.vol"), dir.string()); }, "NaN value");
    write_bytes(dir / "a.txt", {'x'});
    expect_scene_error([&] { make_volume(grid_props("a.txt"), dir.string()); },
                       "unknown volume file type");
    {
        Properties p = grid_props("a.vol");
        p.set("filter_type", std::string("cubic"), SourceLocation{"scene.xml", 6});
        expect_scene_error([&] { make_volume(p, dir.string()); }, "scene.xml:6:");
        expect_scene_error([&] { make_volume(p, dir.string()); }, "unknown filter type \"cubic\"");
    }
    {
        Properties p("volume", "perlin", SourceLocation{"scene.xml", 3});
        expect_scene_error([&] { make_volume(p, dir.string()); }, "unknown volume type");
    }
}

// The DDA visits the cells a ray crosses in order: consecutive segments tile the clipped
// interval, and each segment lies in the cell whose majorant it reports.
TEST(MajorantGrid, TraversalVisitsCellsInOrder) {
    GridVolume v(random_grid(24, 16, 9, 1, 21),
                 Transform::translate(Vec3(-1, 0.5f, 2)) * Transform::scale(Vec3(2, 1, 3)));
    MajorantGrid grid(v, 1.0f);
    EXPECT_EQ(grid.resolution(), (std::array<int, 3>{3, 2, 2}));
    Rng rng(StreamKey{3, 0, 1, 0});
    int hits = 0;
    for (int i = 0; i < 20000; ++i) {
        Vec3 o(-3 + 6 * rng.next_1d(), -1 + 3 * rng.next_1d(), 1 + 5 * rng.next_1d());
        Vec3 d = normalize(Vec3(rng.next_1d() - 0.5f, rng.next_1d() - 0.5f, rng.next_1d() - 0.5f));
        if (i % 7 == 0) d = Vec3(1, 0, 0);  // axis-parallel rays
        if (i % 7 == 1) d = Vec3(0, 0, -1);
        const Ray ray(o, d);
        const float t_max = 10 * rng.next_1d();
        float t0, t1;
        auto it = grid.traverse(ray, 0.0f, t_max);
        MajorantSegment seg;
        if (!grid.clip(ray, 0.0f, t_max, t0, t1)) {
            EXPECT_FALSE(it.next(seg));
            continue;
        }
        ++hits;
        float t = t0;
        int count = 0;
        while (it.next(seg)) {
            ASSERT_FLOAT_EQ(seg.t0, t);
            ASSERT_GE(seg.t1, seg.t0);
            t = seg.t1;
            ++count;
            if (seg.t1 - seg.t0 < 1e-4f) continue;
            const Vec3 mid = ray.at(0.5f * (seg.t0 + seg.t1));
            const Vec3 rel = mid - grid.bounds().lo;
            const Vec3 ext = grid.bounds().hi - grid.bounds().lo;
            int cell[3];
            for (int a = 0; a < 3; ++a)
                cell[a] = std::clamp(int(rel[a] / ext[a] * grid.resolution()[a]), 0,
                                     grid.resolution()[a] - 1);
            ASSERT_EQ(seg.majorant, grid.at(cell[0], cell[1], cell[2]));
        }
        EXPECT_NEAR(t, t1, 1e-4f * std::max(1.0f, t1));
        EXPECT_LE(count, 3 + 2 + 2);
    }
    EXPECT_GT(hits, 2000);
}

// The largest amount by which the scaled interpolated density exceeds its cell's majorant, over
// random points in every cell, the cells' corners and points on their faces.
float worst_violation(const Volume& v, const MajorantGrid& grid, float scale, int points_per_cell) {
    Rng rng(StreamKey{99, 0, 1, 0});
    float worst = -kInfinity;
    const auto res = grid.resolution();
    for (int z = 0; z < res[2]; ++z)
        for (int y = 0; y < res[1]; ++y)
            for (int x = 0; x < res[0]; ++x) {
                const Aabb box = grid.cell_bounds(x, y, z);
                const float majorant = grid.at(x, y, z);
                auto check = [&](Vec3 f) {
                    const Vec3 p = box.lo + (box.hi - box.lo) * f;
                    worst = std::max(worst, scale * v.eval(p).max() - majorant);
                };
                for (int i = 0; i < points_per_cell; ++i)
                    check(Vec3(rng.next_1d(), rng.next_1d(), rng.next_1d()));
                for (int c = 0; c < 8; ++c)
                    check(
                        Vec3((c & 1) ? 1.0f : 0.0f, (c & 2) ? 1.0f : 0.0f, (c & 4) ? 1.0f : 0.0f));
                for (int i = 0; i < points_per_cell / 4; ++i) {
                    Vec3 f(rng.next_1d(), rng.next_1d(), rng.next_1d());
                    const int axis = i % 3;
                    f[axis] = (i / 3) % 2 ? 1.0f : 0.0f;  // a point on a face
                    check(f);
                }
            }
    return worst;
}

// Random values on a steep exponential trend: a cell's neighbours are often larger than all its
// own voxels, so interpolation across its faces exceeds them (spiky white noise alone would not
// show a missing neighbour: every cell then holds a spike of its own).
VolumeGridData trend_grid(int nx, int ny, int nz, int channels, uint64_t seed) {
    Rng rng(StreamKey{seed, 0, 1, 0});
    return make_grid(nx, ny, nz, channels, [&](int x, int y, int z, int c) {
        const float trend =
            std::exp(0.3f * float(x) - 0.2f * float(y) + (c == 1 ? 0.25f : -0.1f) * float(z));
        return trend * (0.7f + 0.3f * rng.next_1d());
    });
}

TEST(MajorantGrid, BoundsTheInterpolatedDensityEverywhere) {
    // Random grids (odd sizes, so majorant cells do not align with 8 voxels), axis-aligned and
    // rotated, one and three channels.
    const Transform rotated = Transform::translate(Vec3(0.3f, -2, 1)) *
                              Transform::rotate(Vec3(1, 2, 3), 37.0f) *
                              Transform::scale(Vec3(2, 1, 0.5f));
    for (int channels : {1, 3})
        for (const Transform& to_world : {Transform(), rotated}) {
            SCOPED_TRACE(channels);
            GridVolume spiky(random_grid(21, 17, 13, channels, 5 + channels), to_world);
            EXPECT_LE(worst_violation(spiky, MajorantGrid(spiky, 2.5f), 2.5f, 3000), 0.0f);
            GridVolume trend(trend_grid(21, 17, 13, channels, 9 + channels), to_world);
            EXPECT_LE(worst_violation(trend, MajorantGrid(trend, 2.5f), 2.5f, 3000), 0.0f);
            // Nearest-neighbour look-ups need no neighbours; their bound holds too.
            GridVolume nearest(trend_grid(21, 17, 13, channels, 9 + channels), to_world,
                               VolumeFilter::kNearest);
            EXPECT_LE(worst_violation(nearest, MajorantGrid(nearest, 2.5f), 2.5f, 3000), 0.0f);
        }
    // Forgetting the voxels that interpolation reads across a cell's faces is caught. (Axis-
    // aligned only: for a rotated grid a world cell's box in grid space is so much larger than
    // the cell that it holds the neighbours anyway.)
    for (int channels : {1, 3}) {
        GridVolume unsafe(trend_grid(21, 17, 13, channels, 9 + channels), Transform());
        unsafe.include_interpolation_neighbours = false;
        EXPECT_GT(worst_violation(unsafe, MajorantGrid(unsafe, 2.5f), 2.5f, 3000), 0.01f)
            << channels;
    }

    // The shipped smoke grid, placed as in scenes/smoke/scene.xml.
    VolumeGridData smoke =
        read_vol_file(std::string(RENDER_SOURCE_DIR) + "/scenes/smoke/smoke.vol");
    const Transform placement = Transform::translate(Vec3(0, -0.29f, 0)) *
                                Transform::scale(Vec3(0.55f, 0.7f, 0.55f)) *
                                Transform::scale(Vec3(2.0f)) * Transform::translate(Vec3(-0.5f));
    GridVolume v(smoke, placement);
    MajorantGrid grid(v, 1.0f);
    EXPECT_LE(worst_violation(v, grid, 1.0f, 600), 0.0f);
    GridVolume unsafe(smoke, placement);
    unsafe.include_interpolation_neighbours = false;
    MajorantGrid unsafe_grid(unsafe, 1.0f);
    EXPECT_GT(worst_violation(unsafe, unsafe_grid, 1.0f, 600), 0.0f);
    // The majorants are tight enough to be useful: well below the global maximum somewhere.
    int loose = 0;
    const auto res = grid.resolution();
    for (int z = 0; z < res[2]; ++z)
        for (int y = 0; y < res[1]; ++y)
            for (int x = 0; x < res[0]; ++x) loose += grid.at(x, y, z) < 0.5f * v.max_value();
    EXPECT_GT(loose, res[0] * res[1] * res[2] / 4);
}

TEST(MajorantGrid, ConstantVolumeIsOneInfiniteCell) {
    ConstantVolume c(Rgb(0.5f, 2.0f, 1.0f));
    MajorantGrid grid(c, 3.0f);
    EXPECT_FALSE(grid.bounded());
    auto it = grid.traverse(Ray(Vec3(0.0f), Vec3(0, 0, 1)), 0.0f, kInfinity);
    MajorantSegment seg;
    ASSERT_TRUE(it.next(seg));
    EXPECT_EQ(seg.t0, 0.0f);
    EXPECT_EQ(seg.t1, kInfinity);
    EXPECT_EQ(seg.majorant, 6.0f);
    EXPECT_FALSE(it.next(seg));
}

}  // namespace
}  // namespace render
