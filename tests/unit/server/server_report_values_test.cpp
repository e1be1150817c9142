// A report's values as the server receives them (server/report_values.h): in memory or spooled
// to an unlinked file, in chunks that split values, and merged block by block into a frame's
// sums exactly as from whole buffers.

#include "server/report_values.h"

#include <gtest/gtest.h>
#include <signal.h>
#include <sys/resource.h>
#include <unistd.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "core/render/render_iterations.h"
#include "server/accumulator.h"
#include "tests/support/temp_dir.h"

using namespace render;
using namespace render::server;
namespace fs = std::filesystem;

namespace {

fs::path temp_dir(const std::string& name) {
    return render::testing::fresh_temp_dir("server_report_values_test", name);
}

std::vector<double> random_values(size_t n, uint64_t seed) {
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> exponent(-6.0, 3.0);
    std::vector<double> v(n);
    for (double& x : v) x = std::pow(10.0, exponent(rng));
    return v;
}

std::string bytes_of(const std::vector<double>& values) {
    return std::string(reinterpret_cast<const char*>(values.data()),
                       values.size() * sizeof(double));
}

// Appends `bytes` in chunks of the given sizes (cycled), as gRPC messages would bring them.
std::string append_in_chunks(ReportValues& values, const std::string& bytes,
                             const std::vector<size_t>& sizes) {
    size_t at = 0;
    for (size_t k = 0; at < bytes.size(); ++k) {
        const size_t n = std::min(sizes[k % sizes.size()], bytes.size() - at);
        if (std::string error = values.append(std::string_view(bytes).substr(at, n));
            !error.empty())
            return error;
        at += n;
    }
    return "";
}

size_t entries(const fs::path& dir) {
    return size_t(std::distance(fs::directory_iterator(dir), fs::directory_iterator()));
}

}  // namespace

// Values split between chunks (sizes not multiples of 8) come back whole, from memory and from
// the spool file, and the spool file has no name in its folder.
TEST(ReportValues, ChunksThatSplitValuesComeBackWholeInMemoryAndSpooled) {
    const fs::path dir = temp_dir("whole");
    const std::vector<double> sent = random_values(5000, 1);
    const std::string bytes = bytes_of(sent);
    ReportValues memory = ReportValues::in_memory(sent.size());
    ReportValues spooled = ReportValues::spooled(dir / "spool", sent.size());
    EXPECT_FALSE(memory.is_spooled());
    EXPECT_TRUE(spooled.is_spooled());
    EXPECT_EQ(entries(dir / "spool"), 0u) << "the spool file has a name";
    EXPECT_EQ(append_in_chunks(memory, bytes, {1, 7, 13, 4099, 3}), "");
    EXPECT_EQ(append_in_chunks(spooled, bytes, {5, 8, 1021, 2}), "");
    EXPECT_TRUE(memory.complete());
    EXPECT_TRUE(spooled.complete());
    std::vector<double> scratch;
    for (ReportValues* v : {&memory, &spooled}) {
        const std::span<const double> all = v->block(0, sent.size(), scratch);
        EXPECT_EQ(std::vector<double>(all.begin(), all.end()), sent);
        const std::span<const double> middle = v->block(1234, 17, scratch);
        EXPECT_EQ(std::vector<double>(middle.begin(), middle.end()),
                  std::vector<double>(sent.begin() + 1234, sent.begin() + 1251));
        EXPECT_THROW(v->block(4990, 11, scratch), std::out_of_range);
    }
    spooled.release();
    EXPECT_FALSE(spooled.is_spooled());
    EXPECT_EQ(entries(dir / "spool"), 0u);
    fs::remove_all(dir);
}

// A value that is not finite is refused when its last byte arrives, named by its index, even
// when its bytes come in two chunks; more bytes than announced are refused; a block past what
// arrived is not read.
TEST(ReportValues, RefusesNonFiniteValuesAndExtraBytesAsTheyArrive) {
    const fs::path dir = temp_dir("refuse");
    for (const double bad :
         {std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::infinity(),
          -std::numeric_limits<double>::infinity()}) {
        std::vector<double> sent = random_values(100, 2);
        sent[41] = bad;
        const std::string bytes = bytes_of(sent);
        for (bool spool : {false, true}) {
            ReportValues v = spool ? ReportValues::spooled(dir, sent.size())
                                   : ReportValues::in_memory(sent.size());
            // Value 41 occupies bytes [328, 336): the first chunk ends inside it.
            EXPECT_EQ(v.append(std::string_view(bytes).substr(0, 331)), "");
            EXPECT_EQ(v.append(std::string_view(bytes).substr(331)),
                      "report value 41 is not finite");
        }
    }
    const std::string nine_values = bytes_of(random_values(9, 3));
    for (bool spool : {false, true}) {
        ReportValues v = spool ? ReportValues::spooled(dir, 8) : ReportValues::in_memory(8);
        EXPECT_EQ(v.append(std::string_view(nine_values).substr(0, 20)), "");
        std::vector<double> scratch;
        EXPECT_EQ(v.block(0, 2, scratch).size(), 2u);
        EXPECT_THROW(v.block(0, 3, scratch), std::out_of_range);  // value 2 is half here
        EXPECT_EQ(v.append(std::string_view(nine_values).substr(20)),
                  "report has more than the expected 64 bytes of values");
        EXPECT_FALSE(v.complete());
    }
    fs::remove_all(dir);
}

// A spool folder that cannot be made is an error naming it (the server then receives the
// report in memory); a write that fails (here the file size limit, as a full disk would) is
// reported as the spool's failure, not the report's.
TEST(ReportValues, SpoolFailuresAreTheServersNotTheReports) {
    const fs::path dir = temp_dir("fail");
    std::ofstream(dir / "a-file") << "x";
    try {
        ReportValues::spooled(dir / "a-file" / "spool", 4);
        ADD_FAILURE() << "a spool folder under a file was made";
    } catch (const std::runtime_error& e) {
        EXPECT_NE(std::string(e.what()).find("a-file"), std::string::npos) << e.what();
    }
    const std::string bytes = bytes_of(random_values(2048, 4));  // 16 KiB
    struct rlimit old {};
    ASSERT_EQ(::getrlimit(RLIMIT_FSIZE, &old), 0);
    auto* old_handler = ::signal(SIGXFSZ, SIG_IGN);  // EFBIG instead of the signal
    struct rlimit small = old;
    small.rlim_cur = 4096;
    ASSERT_EQ(::setrlimit(RLIMIT_FSIZE, &small), 0);
    ReportValues v = ReportValues::spooled(dir / "spool", 2048);
    bool spool_failed = false;
    const std::string error = v.append(bytes, &spool_failed);
    ::setrlimit(RLIMIT_FSIZE, &old);
    ::signal(SIGXFSZ, old_handler);
    EXPECT_TRUE(spool_failed);
    EXPECT_EQ(error.rfind("cannot spool the report to " + (dir / "spool").string(), 0), 0u)
        << error;
    // A report's own fault does not set it.
    ReportValues w = ReportValues::in_memory(1);
    bool flag = false;
    EXPECT_FALSE(w.append(bytes_of({std::nan("")}), &flag).empty());
    EXPECT_FALSE(flag);
    fs::remove_all(dir);
}

// A frame's sums after reports merged block by block from spooled values equal, bit for bit,
// the sums (and the fused relative-error estimate) after the same reports from whole buffers:
// several iterations with odd_sum, one odd and one even iteration without it, and technique
// layers. The frame has more values than one block (2^17), so a block boundary and a short
// last block are crossed.
TEST(ReportValues, SpooledReportsMergeBitForBitAsWholeBuffers) {
    const fs::path dir = temp_dir("merge");
    constexpr int kWidth = 300, kHeight = 160;  // 144,000 values per buffer
    const size_t n = size_t(kWidth) * kHeight * 3;
    FrameAccumulator whole(kWidth, kHeight, LayerMode::Techniques);
    FrameAccumulator blocks(kWidth, kHeight, LayerMode::Techniques);
    const size_t layers = whole.layer_count();
    ASSERT_GT(layers, 0u);
    uint64_t seed = 10;
    struct Report {
        Range range;
        uint64_t odd_count;
        bool odd_omitted;
    };
    for (const Report& r : {Report{{1, 4}, 2, false}, Report{{4, 5}, 0, true},
                            Report{{5, 6}, 1, true}, Report{{6, 9}, 1, false}}) {
        const std::vector<double> sum = random_values(n, seed++);
        const std::vector<double> odd =
            r.odd_omitted ? std::vector<double>{} : random_values(n, seed++);
        const std::vector<double> layer_sums = random_values(layers * n, seed++);
        whole.add(r.range, sum, odd, layer_sums, r.odd_count, {});
        ReportValues v = ReportValues::spooled(dir, (r.odd_omitted ? 1 : 2) * n + layers * n);
        ASSERT_EQ(append_in_chunks(v, bytes_of(sum) + bytes_of(odd) + bytes_of(layer_sums),
                                   {1 << 20, 4093}),
                  "");
        blocks.add(r.range, v, r.odd_omitted, r.odd_count, {});
        ASSERT_EQ(blocks.result().sum.values(), whole.result().sum.values());
        ASSERT_EQ(blocks.result().odd_sum.values(), whole.result().odd_sum.values());
        for (size_t l = 0; l < layers; ++l)
            ASSERT_EQ(blocks.result().layers.buffer(l).values(),
                      whole.result().layers.buffer(l).values());
        EXPECT_EQ(blocks.relative_error(), whole.relative_error());
        EXPECT_EQ(blocks.relative_error(), estimate_relative_error(blocks.result()));
    }
    EXPECT_EQ(blocks.count(), 8u);
    // Estimated (random values: not small), not the 1 of "unknown".
    EXPECT_GT(blocks.relative_error(), 0.0);
    EXPECT_NE(blocks.relative_error(), 1.0);
    // An incomplete report, or one of the wrong size, is not added.
    ReportValues half = ReportValues::in_memory(2 * n + layers * n);
    ASSERT_EQ(half.append(bytes_of(random_values(n, 99))), "");
    EXPECT_THROW(blocks.add({9, 11}, half, false, 1, {}), std::invalid_argument);
    ReportValues omitted = ReportValues::in_memory(n + layers * n);
    ASSERT_EQ(omitted.append(bytes_of(random_values(n + layers * n, 98))), "");
    EXPECT_THROW(blocks.add({9, 11}, omitted, true, 1, {}), std::invalid_argument);
    EXPECT_EQ(blocks.count(), 8u);
    fs::remove_all(dir);
}
