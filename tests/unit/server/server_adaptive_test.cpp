// The server's side of adaptive sampling (docs/reference/adaptive-sampling.md, "The service"):
// the scheduler's rounds, the accumulator's exact sums, counts and masks and their checkpoint,
// the mask's packing, a report's exact-sum words, and a farm merged through the accumulator
// against `render`'s one-process loop.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include "core/render/adaptive_rounds.h"
#include "core/render/render_iterations.h"
#include "core/scene/loader/scene_loader.h"
#include "server/accumulator.h"
#include "server/report_values.h"
#include "server/scheduler.h"
#include "service/mask_bits.h"
#include "tests/support/temp_dir.h"

using namespace render;
using namespace render::server;
namespace fs = std::filesystem;

namespace {

struct FakeClock {
    TimePoint now = TimePoint{} + std::chrono::hours(1);
};

RenderSettings adaptive_settings(double threshold = 0.1) {
    RenderSettings settings;
    settings.algorithm = "pt";
    settings.seed = 3;
    settings.threads = 2;
    settings.adaptive = threshold;
    settings.adaptive_min_iterations = 8;
    settings.adaptive_round = 4;
    return settings;
}

// Leases everything `worker` can get now, merging each lease at once; returns the ranges.
std::vector<Range> lease_all(Scheduler& s, const std::string& worker) {
    std::vector<Range> out;
    while (auto g = s.lease(worker)) {
        LeaseGrant merged;
        EXPECT_EQ(s.begin_merge(g->lease_id, 0.0, &merged), MergeDecision::Accept);
        s.end_merge(merged);
        out.push_back(g->range);
    }
    return out;
}

}  // namespace

TEST(AdaptiveScheduler, LeasesStayWithinTheRoundUntilItIsOpened) {
    FakeClock clock;
    Scheduler s(SchedulerOptions{10, 3}, [&] { return clock.now; });
    FramePlan plan;
    plan.target = 30;
    plan.round_end = 9;  // round 0: iterations 1..8
    s.add_job("j", 0, 1, JobState::Queued, {plan});
    std::vector<Range> got = lease_all(s, "w");
    ASSERT_FALSE(got.empty());
    for (const Range& r : got) EXPECT_LE(r.end, 9u) << r.first << ".." << r.end;
    EXPECT_EQ(got.back().end, 9u);
    // The round is wholly merged: its boundary is reported (at every call) and nothing leased.
    EXPECT_EQ(s.round_boundaries(), (std::vector<std::pair<std::string, uint32_t>>{{"j", 0}}));
    EXPECT_EQ(s.round_boundaries().size(), 1u);
    EXPECT_FALSE(s.lease("w"));
    EXPECT_TRUE(s.tick().empty()) << "a frame at a round boundary is not complete";
    s.open_round("j", 0, 13);
    EXPECT_TRUE(s.round_boundaries().empty());
    got = lease_all(s, "w");
    ASSERT_FALSE(got.empty());
    EXPECT_EQ(got.front().first, 9u);
    EXPECT_EQ(got.back().end, 13u);
    // The next boundary; closing the frame (no pixel left) completes it at 12 iterations.
    EXPECT_EQ(s.round_boundaries().size(), 1u);
    s.close_frame("j", 0);
    EXPECT_TRUE(s.round_boundaries().empty());
    EXPECT_EQ(s.tick().size(), 1u);
    EXPECT_EQ(s.progress("j", 0).merged, 12u);
}

TEST(AdaptiveScheduler, ABoundaryWaitsForEveryRangeOfTheRound) {
    FakeClock clock;
    Scheduler s(SchedulerOptions{10, 3}, [&] { return clock.now; });
    FramePlan plan;
    plan.target = 100;
    plan.round_end = 3;
    s.add_job("j", 0, 1, JobState::Queued, {plan});
    auto a = s.lease("a");
    auto b = s.lease("b");
    ASSERT_TRUE(a && b);
    EXPECT_EQ(a->range.first, 1u);
    EXPECT_EQ(b->range.end, 3u);
    EXPECT_FALSE(s.lease("c")) << "nothing past the round";
    LeaseGrant g;
    ASSERT_EQ(s.begin_merge(b->lease_id, 0, &g), MergeDecision::Accept);
    s.end_merge(g);
    EXPECT_TRUE(s.round_boundaries().empty()) << "iteration 1 is not merged";
    // a's worker dies: its range expires and goes to c, still within the round.
    clock.now += std::chrono::seconds(11);
    EXPECT_EQ(s.tick().size(), 0u);
    auto c = s.lease("c");
    ASSERT_TRUE(c);
    EXPECT_EQ(c->range.first, 1u);
    EXPECT_EQ(c->range.end, 2u);
    ASSERT_EQ(s.begin_merge(c->lease_id, 0, &g), MergeDecision::Accept);
    s.end_merge(g);
    EXPECT_EQ(s.round_boundaries().size(), 1u);
}

TEST(AdaptiveScheduler, ARoundEndingAtTheTargetCompletesTheFrame) {
    FakeClock clock;
    Scheduler s(SchedulerOptions{10, 3}, [&] { return clock.now; });
    FramePlan plan;
    plan.target = 8;
    plan.round_end = 9;
    s.add_job("j", 0, 1, JobState::Queued, {plan});
    lease_all(s, "w");
    EXPECT_TRUE(s.round_boundaries().empty());
    EXPECT_EQ(s.tick().size(), 1u);
}

TEST(AdaptiveScheduler, ARestoredRoundLeasesItsMissingRangesFirst) {
    FakeClock clock;
    Scheduler s(SchedulerOptions{10, 3}, [&] { return clock.now; });
    FramePlan plan;
    plan.target = 100;
    plan.round_end = 13;  // round 1 (9..12) of a checkpoint holding 1..9 and 11..12
    plan.merged.add({1, 10});
    plan.merged.add({11, 13});
    s.add_job("j", 0, 1, JobState::Running, {plan});
    std::vector<Range> got = lease_all(s, "w");
    ASSERT_EQ(got.size(), 1u);
    EXPECT_EQ(got[0].first, 10u);
    EXPECT_EQ(got[0].end, 11u);
    EXPECT_EQ(s.round_boundaries().size(), 1u);
}

TEST(MaskBits, PackAndUnpackRoundTrip) {
    for (size_t pixels : {1u, 7u, 8u, 9u, 1000u}) {
        std::vector<uint8_t> mask(pixels);
        for (size_t p = 0; p < pixels; ++p) mask[p] = (p * 7 + 3) % 5 < 2;
        const std::string packed = service::pack_mask(mask);
        EXPECT_EQ(packed.size(), (pixels + 7) / 8);
        EXPECT_EQ(service::unpack_mask(packed, pixels), mask);
    }
    EXPECT_THROW(service::unpack_mask(std::string(2, '\0'), 8), std::invalid_argument);
    EXPECT_THROW(service::unpack_mask(std::string(1, '\x80'), 7), std::invalid_argument)
        << "a bit past the last pixel";
}

TEST(AdaptiveReportValues, ExactSumWordsAreCheckedAgainstTheirRange) {
    const fs::path dir = render::testing::fresh_temp_dir("server_adaptive_test", "words");
    const ReportValues::Words words{2, 100};
    // Two float64 values, then two int64 words; sent in 5-byte pieces (values split between
    // chunks), held in memory and spooled.
    auto append = [&](bool spool, double second, int64_t last) {
        std::vector<char> bytes(4 * 8);
        const double first = 1.5;
        const int64_t ok = 100;
        std::memcpy(bytes.data(), &first, 8);
        std::memcpy(bytes.data() + 8, &second, 8);
        std::memcpy(bytes.data() + 16, &ok, 8);
        std::memcpy(bytes.data() + 24, &last, 8);
        ReportValues v =
            spool ? ReportValues::spooled(dir, 4, words) : ReportValues::in_memory(4, words);
        for (size_t at = 0; at < bytes.size(); at += 5)
            if (std::string e = v.append(
                    std::string_view(bytes.data() + at, std::min<size_t>(5, bytes.size() - at)));
                !e.empty())
                return e;
        return std::string();
    };
    for (bool spool : {false, true}) {
        SCOPED_TRACE(spool ? "spooled" : "in memory");
        EXPECT_EQ(append(spool, 2.0, 0), "");
        EXPECT_NE(append(spool, 2.0, 101).find("exact sum 1 is 101"), std::string::npos);
        EXPECT_NE(append(spool, 2.0, -1).find("exact sum 1 is -1"), std::string::npos);
        // Before `from` a value is still a float64 that must be finite.
        EXPECT_NE(append(spool, std::nan(""), 0).find("value 1 is not finite"), std::string::npos);
    }
}

namespace {

std::unique_ptr<Scene> cornell_box(int size) {
    return load_scene(std::string(RENDER_SOURCE_DIR) + "/scenes/bitterli/cornell-box/scene_v3.xml",
                      {{"resx", std::to_string(size)}, {"resy", std::to_string(size)}});
}

// Adds a worker's range result to the accumulator as a report carries it (the odd sums
// omitted for one iteration, as the worker omits them).
void add_report(FrameAccumulator& acc, Range range, const IterationResult& part) {
    const bool omit = range.size() == 1;
    acc.add(range, part.sum.values(),
            omit ? std::span<const double>() : std::span<const double>(part.odd_sum.values()), {},
            part.odd_count, part.stats, part.adaptive.exact.sums(),
            omit ? std::span<const int64_t>()
                 : std::span<const int64_t>(part.adaptive.exact.odd_sums()));
}

}  // namespace

// The server's merge (FrameAccumulator with its rounds and masks) of a farm's reports equals
// `render`'s one-process loop: exact sums and counts bit for bit, the image and the samples
// layer as floats exactly; and the accumulator saved and loaded in the middle of a round
// brings back its round and mask.
TEST(AdaptiveAccumulator, AFarmMergedByTheServerEqualsRender) {
    constexpr int kSize = 16;
    constexpr uint64_t kIterations = 40;
    auto scene = cornell_box(kSize);
    const RenderSettings settings = adaptive_settings(0.15);
    const AdaptiveRounds rounds(settings);

    IterationRenderer alone(*scene, settings, 0);
    IterationResult expected = alone.empty_result();
    uint64_t stopped_at = kIterations;
    for (uint64_t i = 1; i <= kIterations; ++i) {
        if (alone.adaptive_active_pixels(expected) == 0) {
            stopped_at = i - 1;
            break;
        }
        alone.add_adaptive({i, i + 1}, expected);
    }

    const fs::path dir = render::testing::fresh_temp_dir("server_adaptive_test", "farm");
    FrameAccumulator acc(kSize, kSize, settings);
    ASSERT_TRUE(acc.adaptive());
    bool saved = false;
    for (uint64_t round = 0;; ++round) {
        ASSERT_EQ(acc.round(), round);
        const uint64_t first = rounds.first(round);
        const uint64_t end = std::min(rounds.end(round), kIterations + 1);
        // Three "workers" per round, reported in reverse order, ranges of uneven sizes.
        std::vector<Range> ranges;
        for (uint64_t a = first; a < end;) {
            const uint64_t b = std::min(end, a + 1 + (a % 3));
            ranges.push_back({a, b});
            a = b;
        }
        std::reverse(ranges.begin(), ranges.end());
        for (size_t k = 0; k < ranges.size(); ++k) {
            IterationRenderer worker(*scene, settings, 0);
            IterationResult part = worker.empty_result();
            worker.add({ranges[k].first, ranges[k].end}, part,
                       round == 0 ? std::span<const uint8_t>() : std::span(acc.mask()));
            add_report(acc, ranges[k], part);
            if (round == 2 && k == 0 && !saved) {
                // A restart mid-round: the round and its mask come back from the checkpoint.
                acc.save(dir / "f.ckpt", 1.0);
                FrameAccumulator back = FrameAccumulator::load(dir / "f.ckpt", nullptr);
                EXPECT_EQ(back.round(), acc.round());
                EXPECT_EQ(back.mask(), acc.mask());
                EXPECT_EQ(back.mask_sha256(), acc.mask_sha256());
                EXPECT_EQ(back.result().adaptive.count, acc.result().adaptive.count);
                EXPECT_EQ(back.result().adaptive.exact.sums(), acc.result().adaptive.exact.sums());
                acc = std::move(back);
                saved = true;
            }
        }
        if (end == kIterations + 1) break;
        ASSERT_TRUE(acc.round_complete());
        std::vector<uint8_t> mask = acc.next_round_mask(settings);
        if (std::count(mask.begin(), mask.end(), 1) == 0) break;
        acc.start_next_round(std::move(mask));
        EXPECT_FALSE(acc.round_complete());
    }
    ASSERT_TRUE(saved) << "the render ended before round 2: make the threshold smaller";
    EXPECT_EQ(acc.count(), stopped_at);
    const IterationResult& got = acc.result();
    EXPECT_EQ(got.adaptive.count, expected.adaptive.count);
    EXPECT_EQ(got.adaptive.odd_count, expected.adaptive.odd_count);
    EXPECT_EQ(got.adaptive.exact.sums(), expected.adaptive.exact.sums());
    EXPECT_EQ(got.adaptive.exact.odd_sums(), expected.adaptive.exact.odd_sums());
    const uint64_t most = *std::max_element(got.adaptive.count.begin(), got.adaptive.count.end());
    const uint64_t least = *std::min_element(got.adaptive.count.begin(), got.adaptive.count.end());
    EXPECT_LT(least, most) << "the masks did nothing";
    const Image a = acc.average(), b = mean_image(expected);
    for (size_t p = 0; p < a.pixel_count(); ++p)
        for (int c = 0; c < 3; ++c) EXPECT_EQ(a.at(p)[c], b.at(p)[c]) << "pixel " << p;
    const std::vector<NamedLayer> layers = acc.layer_averages();
    ASSERT_EQ(layers.size(), 1u);
    EXPECT_EQ(layers[0].name, "samples");
    for (size_t p = 0; p < layers[0].image.pixel_count(); ++p)
        EXPECT_EQ(layers[0].image.at(p)[0], float(expected.adaptive.count[p]));
    EXPECT_DOUBLE_EQ(acc.relative_error(), estimate_relative_error(expected));
}

TEST(AdaptiveAccumulator, RefusesARangeOutsideItsRoundAndChecksCheckpointsRounds) {
    const RenderSettings settings = adaptive_settings();
    FrameAccumulator acc(2, 1, settings);
    std::vector<double> sum(6, 0.5), odd(6, 0.25);
    std::vector<int64_t> exact(2, 5), exact_odd(2, 2);
    // Iterations 8..9 span rounds 0 and 1.
    EXPECT_THROW(acc.add({8, 10}, sum, odd, {}, 1, RenderStats{}, exact, exact_odd),
                 std::invalid_argument);
    // Missing exact sums.
    EXPECT_THROW(acc.add({1, 3}, sum, odd, {}, 1, RenderStats{}), std::invalid_argument);
    EXPECT_FALSE(acc.round_complete());
    EXPECT_EQ(acc.count(), 0u);
    acc.add({1, 3}, sum, odd, {}, 1, RenderStats{}, exact, exact_odd);
    EXPECT_EQ(acc.result().adaptive.count, (std::vector<uint64_t>{2, 2}));
    EXPECT_EQ(acc.result().adaptive.odd_count, (std::vector<uint64_t>{1, 1}));
    // A checkpoint of an accumulator that is not adaptive keeps the version-2 format and
    // has no rounds; an adaptive one says its rounds.
    const fs::path dir = render::testing::fresh_temp_dir("server_adaptive_test", "rounds");
    acc.save(dir / "a.ckpt", 0);
    FrameAccumulator back = FrameAccumulator::load(dir / "a.ckpt", nullptr);
    ASSERT_TRUE(back.adaptive());
    EXPECT_EQ(back.rounds().first(1), 9u);
    EXPECT_EQ(back.rounds().end(1), 13u);
    EXPECT_EQ(back.round(), 0u);
    FrameAccumulator plain(2, 1);
    plain.save(dir / "p.ckpt", 0);
    EXPECT_FALSE(FrameAccumulator::load(dir / "p.ckpt", nullptr).adaptive());
}
