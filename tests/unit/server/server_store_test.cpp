// The server's building blocks: SHA-256, bundle path validation, the asset store and the frame
// checkpoints (the job store's tests: server_job_store_test.cpp).

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>

#include "core/render/render_iterations.h"
#include "core/util/sha256.h"
#include "server/accumulator.h"
#include "server/asset_store.h"
#include "server/validation.h"
#include "tests/support/temp_dir.h"

using namespace render;
using namespace render::server;
namespace fs = std::filesystem;

namespace {
fs::path temp_dir(const std::string& name) {
    return render::testing::fresh_temp_dir("server_store_test", name);
}
}  // namespace

TEST(Sha256, KnownVectors) {
    EXPECT_EQ(sha256_hex(""), "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
    EXPECT_EQ(sha256_hex("abc"),
              "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
    EXPECT_EQ(sha256_hex("abcdbcdecdefdefgefghfghighijhijkijkljklmklmnlmnomnopnopq"),
              "248d6a61d20638b8e5c026930c3e6039a33ce45964ff2167f6ecedd419db06c1");
    std::string million(1000000, 'a');
    Sha256 h;
    for (size_t i = 0; i < million.size(); i += 999) h.update(million.substr(i, 999));
    EXPECT_EQ(h.hex_digest(), "cdc76e5c9914fb9281a1c7e284d73e67f1809a48a497200e046d39ccc7112cd0");
    EXPECT_TRUE(is_sha256_hex(sha256_hex("x")));
    EXPECT_FALSE(is_sha256_hex("ABC"));
}

TEST(Validation, BundlePaths) {
    EXPECT_EQ(check_bundle_path("scene.xml"), "");
    EXPECT_EQ(check_bundle_path("meshes/a.obj"), "");
    EXPECT_EQ(check_bundle_path("a..b/c"), "");
    EXPECT_NE(check_bundle_path(""), "");
    EXPECT_NE(check_bundle_path("../../etc/passwd"), "");
    EXPECT_NE(check_bundle_path("a/../../b"), "");
    EXPECT_NE(check_bundle_path("/etc/passwd"), "");
    EXPECT_NE(check_bundle_path("a\\b"), "");
    EXPECT_NE(check_bundle_path("a//b"), "");
    EXPECT_NE(check_bundle_path("./a"), "");
    EXPECT_NE(check_bundle_path("a/.."), "");
}

TEST(AssetStore, UploadChecksHashAndSize) {
    fs::path dir = temp_dir("assets");
    AssetStore store(dir);
    std::string data = "hello asset";
    std::string sha = sha256_hex(data);
    {
        AssetStore::Upload bad(store, sha, data.size());
        EXPECT_EQ(bad.write("hello assex"), "");
        EXPECT_NE(bad.commit(), "");
    }
    EXPECT_FALSE(store.has(sha));
    {
        AssetStore::Upload too_long(store, sha, 3);
        EXPECT_NE(too_long.write(data), "");
    }
    AssetStore::Upload ok(store, sha, data.size());
    EXPECT_EQ(ok.write(data.substr(0, 4)), "");
    EXPECT_EQ(ok.write(data.substr(4)), "");
    EXPECT_EQ(ok.commit(), "");
    EXPECT_EQ(store.size(sha), data.size());
    store.materialize({{"sub/dir/file.txt", sha}}, dir / "job");
    std::ifstream in(dir / "job" / "sub/dir/file.txt");
    std::string read((std::istreambuf_iterator<char>(in)), {});
    EXPECT_EQ(read, data);
    fs::remove_all(dir);
}

// A job with technique layers merges, checkpoints and restores them with the sums (and the
// VPL counters with the other statistics).
TEST(FrameAccumulator, LayersRoundTripThroughTheCheckpoint) {
    fs::path dir = temp_dir("ckpt-layers");
    FrameAccumulator acc(2, 1, render::LayerMode::Techniques);
    ASSERT_EQ(acc.layer_count(), 2u);  // connection, merging
    std::vector<double> sum = {1, 2, 3, 4, 5, 6}, odd = {1, 1, 1, 1, 1, 1};
    std::vector<double> layers = {1, 0, 3, 0, 5, 0, 0, 2, 0, 4, 0, 6};
    EXPECT_THROW(acc.add({1, 2}, sum, odd, {}, 1, {}), std::invalid_argument);
    render::RenderStats stats;
    stats.vpl_candidates = 10;
    stats.vpl_accepted = 3;
    acc.add({1, 2}, sum, odd, layers, 1, stats);
    acc.add({2, 3}, sum, odd, layers, 0, stats);
    acc.save(dir / "f.ckpt", 1.0);
    FrameAccumulator back = FrameAccumulator::load(dir / "f.ckpt", nullptr);
    ASSERT_EQ(back.layer_count(), 2u);
    EXPECT_EQ(back.result().stats.vpl_candidates, 20u);
    EXPECT_EQ(back.result().stats.vpl_accepted, 6u);
    EXPECT_EQ(back.result().layers.buffer(1).values()[5], 12.0);
    std::vector<render::NamedLayer> averages = back.layer_averages();
    ASSERT_EQ(averages.size(), 2u);
    EXPECT_EQ(averages[0].name, "connection");
    EXPECT_EQ(averages[1].image.at(size_t(1)).b, 6.0f);
    fs::remove_all(dir);
}

// A job with the variance layers merges and checkpoints the sum of squares with the sums (one
// buffer more than a job without, which stays as small as before), and writes the same layers
// after a restore as before it (docs/reference/variance-layers.md).
TEST(FrameAccumulator, VarianceSumsRoundTripThroughTheCheckpoint) {
    fs::path dir = temp_dir("ckpt-variance");
    FrameAccumulator plain(2, 1);
    FrameAccumulator acc(2, 1, render::LayerMode::Variance);
    ASSERT_EQ(plain.layer_count(), 0u);
    ASSERT_EQ(acc.layer_count(), 1u);  // the sum of squares
    // Two one-iteration reports: values x1 (odd iteration 1) and x2 (even iteration 2).
    const std::vector<double> x1 = {1, 2, 3, 4, 5, 6}, x2 = {3, 2, 1, 4, 9, 0};
    std::vector<double> q1, q2;
    for (double v : x1) q1.push_back(v * v);
    for (double v : x2) q2.push_back(v * v);
    acc.add({1, 2}, x1, x1, q1, 1, {});
    acc.add({2, 3}, x2, {}, q2, 0, {});
    plain.add({1, 2}, x1, x1, {}, 1, {});
    plain.add({2, 3}, x2, {}, {}, 0, {});
    acc.save(dir / "variance.ckpt", 1.0);
    plain.save(dir / "plain.ckpt", 1.0);
    EXPECT_EQ(fs::file_size(dir / "variance.ckpt"),
              fs::file_size(dir / "plain.ckpt") + x1.size() * sizeof(double));
    FrameAccumulator back = FrameAccumulator::load(dir / "variance.ckpt", nullptr);
    ASSERT_EQ(back.result().layers.mode(), render::LayerMode::Variance);
    const std::vector<render::NamedLayer> before = acc.layer_averages();
    const std::vector<render::NamedLayer> after = back.layer_averages();
    ASSERT_EQ(before.size(), 3u);
    ASSERT_EQ(after.size(), 3u);
    for (size_t l = 0; l < 3; ++l) {
        EXPECT_EQ(before[l].name, after[l].name);
        for (size_t i = 0; i < 6; ++i)
            EXPECT_EQ(before[l].image.data()[i], after[l].image.data()[i]);
    }
    EXPECT_EQ(after[0].name, "variance");
    // Two values a, b: the variance of their mean is (a - b)^2 / 4.
    for (size_t i = 0; i < 6; ++i) {
        EXPECT_FLOAT_EQ(after[0].image.data()[i], float((x1[i] - x2[i]) * (x1[i] - x2[i]) / 4));
        EXPECT_EQ(after[1].image.data()[i], float(x1[i]));  // odd_half
        EXPECT_EQ(after[2].image.data()[i], float(x2[i]));  // even_half
    }
    fs::remove_all(dir);
}

// Checkpoints written before layers existed (format 1) are still read.
TEST(FrameAccumulator, ReadsFormatOneCheckpoints) {
    fs::path dir = temp_dir("ckpt-v1");
    std::string bytes = "RCKP0001";
    auto put = [&](auto v) { bytes.append(reinterpret_cast<const char*>(&v), sizeof v); };
    put(uint32_t(1));  // width
    put(uint32_t(1));  // height
    put(uint64_t(2));  // count
    put(uint64_t(1));  // odd count
    put(uint64_t(2));  // samples
    put(uint64_t(9));  // rays
    put(uint64_t(0));  // non-finite
    put(double(3.5));  // elapsed seconds
    put(uint64_t(1));  // ranges
    put(uint64_t(1));
    put(uint64_t(3));
    for (double v : {2.0, 4.0, 6.0, 1.0, 2.0, 3.0}) put(v);  // sum, odd_sum
    bytes += "RCKP0001";
    fs::create_directories(dir);
    std::ofstream(dir / "old.ckpt", std::ios::binary) << bytes;
    double elapsed = 0;
    FrameAccumulator acc = FrameAccumulator::load(dir / "old.ckpt", &elapsed);
    EXPECT_EQ(acc.count(), 2u);
    EXPECT_EQ(acc.layer_count(), 0u);
    EXPECT_EQ(elapsed, 3.5);
    EXPECT_EQ(acc.average().at(size_t(0)).b, 3.0f);
    fs::remove_all(dir);
}

TEST(FrameAccumulator, CheckpointRoundTrip) {
    fs::path dir = temp_dir("ckpt");
    FrameAccumulator acc(2, 1);
    std::vector<double> sum = {1, 2, 3, 4, 5, 6}, odd = {1, 1, 1, 1, 1, 1};
    render::RenderStats stats;
    stats.samples = 2;
    acc.add({1, 2}, sum, odd, {}, 1, stats);
    acc.add({3, 5}, sum, odd, {}, 1, stats);
    acc.save(dir / "f.ckpt", 4.5);
    double elapsed = 0;
    FrameAccumulator back = FrameAccumulator::load(dir / "f.ckpt", &elapsed);
    EXPECT_DOUBLE_EQ(elapsed, 4.5);
    EXPECT_EQ(back.count(), 3u);
    EXPECT_EQ(back.result().odd_count, 2u);
    EXPECT_EQ(back.result().stats.samples, 4u);
    EXPECT_EQ(back.ranges().ranges().size(), 2u);
    EXPECT_EQ(back.result().sum.values()[5], 12.0);
    EXPECT_EQ(back.average().at(size_t(1)).b, 4.0f);
    // A truncated checkpoint is refused, not half read.
    fs::resize_file(dir / "f.ckpt", fs::file_size(dir / "f.ckpt") - 3);
    EXPECT_THROW(FrameAccumulator::load(dir / "f.ckpt", nullptr), std::runtime_error);
    fs::remove_all(dir);
}

// A one-iteration report may leave odd_sum out: the accumulator adds `sum` to the odd sum for
// an odd iteration and nothing for an even one, bit for bit what adding the worker's odd_sum
// (0 + x, or zeros) would give. Several iterations must send it.
TEST(FrameAccumulator, OneIterationReportsMayOmitTheOddSum) {
    const std::vector<double> odd_image = {0.1, 1e-300, 3.25, 7e10, 0.0, 1.0 / 3.0};
    const std::vector<double> even_image = {0.7, 2.0, 1e-5, 0.2, 5.0, 2.0 / 3.0};
    const std::vector<double> zeros(6, 0.0);
    FrameAccumulator sent(2, 1), derived(2, 1);
    sent.add({1, 2}, odd_image, odd_image, {}, 1, {});
    sent.add({2, 3}, even_image, zeros, {}, 0, {});
    derived.add({1, 2}, odd_image, {}, {}, 1, {});
    derived.add({2, 3}, even_image, {}, {}, 0, {});
    EXPECT_EQ(derived.result().sum.values(), sent.result().sum.values());
    EXPECT_EQ(derived.result().odd_sum.values(), sent.result().odd_sum.values());
    EXPECT_EQ(derived.result().odd_sum.values()[2], 3.25);
    EXPECT_EQ(derived.result().odd_count, 1u);
    EXPECT_EQ(derived.relative_error(), sent.relative_error());
    EXPECT_THROW(derived.add({3, 5}, odd_image, {}, {}, 1, {}), std::invalid_argument);
}

// The accumulator estimates the relative error in the addition's pass (one pass over the sums
// per report, not two): the value must be estimate_relative_error's of the merged sums bit for
// bit after every kind of report (several iterations, one odd or even iteration without its odd
// sum), and after a checkpoint is read back. Values span 1e-6..1e3 so that the rounding of
// the sums' terms would show a different order or operation.
TEST(FrameAccumulator, TheFusedErrorEstimateEqualsCoresBitForBit) {
    fs::path dir = temp_dir("ckpt-error");
    constexpr int kWidth = 64, kHeight = 32;
    const size_t n = size_t(kWidth) * kHeight * 3;
    std::mt19937_64 rng(7);
    std::uniform_real_distribution<double> exponent(-6.0, 3.0);
    auto image = [&] {
        std::vector<double> v(n);
        for (double& x : v) x = std::pow(10.0, exponent(rng));
        return v;
    };
    FrameAccumulator acc(kWidth, kHeight);
    EXPECT_EQ(acc.relative_error(), 1.0);  // nothing merged
    // [1, 2) alone: only odd iterations, the estimate is unknown (1).
    const std::vector<double> first = image();
    acc.add({1, 2}, first, {}, {}, 1, {});
    EXPECT_EQ(acc.relative_error(), 1.0);
    EXPECT_EQ(render::estimate_relative_error(acc.result()), 1.0);
    // [2, 3) even, odd sum omitted; [3, 6) sent with its odd sum; [6, 7) even; [7, 8) odd.
    acc.add({2, 3}, image(), {}, {}, 0, {});
    EXPECT_EQ(acc.relative_error(), render::estimate_relative_error(acc.result()));
    EXPECT_GT(acc.relative_error(), 0.0);
    EXPECT_LT(acc.relative_error(), 1.0);
    std::vector<double> three = image(), odd_of_three = image();
    for (size_t i = 0; i < n; ++i) three[i] += odd_of_three[i];  // 3 and 5 odd, 4 even
    acc.add({3, 6}, three, odd_of_three, {}, 2, {});
    EXPECT_EQ(acc.relative_error(), render::estimate_relative_error(acc.result()));
    acc.add({6, 7}, image(), {}, {}, 0, {});
    EXPECT_EQ(acc.relative_error(), render::estimate_relative_error(acc.result()));
    acc.add({7, 8}, image(), {}, {}, 1, {});
    const double merged = acc.relative_error();
    EXPECT_EQ(merged, render::estimate_relative_error(acc.result()));
    acc.save(dir / "f.ckpt", 1.0);
    EXPECT_EQ(FrameAccumulator::load(dir / "f.ckpt", nullptr).relative_error(), merged);
    // A black frame has no relative error (0), as in core.
    FrameAccumulator black(2, 1);
    const std::vector<double> zeros(6, 0.0);
    black.add({1, 2}, zeros, {}, {}, 1, {});
    black.add({2, 3}, zeros, {}, {}, 0, {});
    EXPECT_EQ(black.relative_error(), 0.0);
    EXPECT_EQ(render::estimate_relative_error(black.result()), 0.0);
    fs::remove_all(dir);
}
