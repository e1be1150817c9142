// The server's per-report merge of a 3840x2160 frame (docs/results/performance-notes.md, "Costs
// that grow with the work"): adding a two-iteration report's sum and odd sum into the frame's
// float64 sums and estimating the relative error that the progress, the dashboard's error plot and
// --target-error read after every merge.
//   merge/fused: FrameAccumulator::add, which takes the estimate's sums in its own pass;
//   merge/add_then_estimate: the addition and then core's estimate_relative_error, a second
//   pass over the sums (what the server did before).
// Both give the same sums and the same estimate (unit test
// FrameAccumulator.TheFusedErrorEstimateEqualsCoresBitForBit).

#include <benchmark/benchmark.h>

#include <random>
#include <vector>

#include "core/render/render_iterations.h"
#include "server/accumulator.h"

namespace render::bench {
namespace {

constexpr int kWidth = 3840, kHeight = 2160;

struct Report {
    std::vector<double> sum, odd_sum;
};

const Report& two_iteration_report() {
    static const Report report = [] {
        const size_t n = size_t(kWidth) * kHeight * 3;
        Report r{std::vector<double>(n), std::vector<double>(n)};
        std::mt19937_64 rng(1);
        std::exponential_distribution<double> radiance(4.0);
        for (size_t i = 0; i < n; ++i) {
            r.odd_sum[i] = radiance(rng);
            r.sum[i] = r.odd_sum[i] + radiance(rng);
        }
        return r;
    }();
    return report;
}

// The frame after `iterations` merged: reports of iterations [1, 3), [3, 5), ...
server::FrameAccumulator frame() {
    const Report& r = two_iteration_report();
    server::FrameAccumulator acc(kWidth, kHeight);
    acc.add({1, 3}, r.sum, r.odd_sum, {}, 1, {});
    return acc;
}

void merge_fused(benchmark::State& state) {
    const Report& r = two_iteration_report();
    server::FrameAccumulator acc = frame();
    uint64_t first = acc.count() + 1;
    for (auto _ : state) {
        acc.add({first, first + 2}, r.sum, r.odd_sum, {}, 1, {});
        benchmark::DoNotOptimize(acc.relative_error());
        first += 2;
    }
    state.SetBytesProcessed(int64_t(state.iterations()) * int64_t(4 * r.sum.size() * 8));
}

// The addition as FrameAccumulator::add did it before (one element-wise pass), then core's
// estimate over the merged sums.
void merge_add_then_estimate(benchmark::State& state) {
    const Report& r = two_iteration_report();
    IterationResult result;
    result.sum = AccumulationBuffer(kWidth, kHeight);
    result.odd_sum = AccumulationBuffer(kWidth, kHeight);
    uint64_t count = 0, odd_count = 0;
    auto add = [&] {
        auto& s = result.sum.values();
        auto& o = result.odd_sum.values();
        for (size_t i = 0; i < s.size(); ++i) {
            s[i] += r.sum[i];
            o[i] += r.odd_sum[i];
        }
        result.count = count += 2;
        result.odd_count = odd_count += 1;
    };
    add();
    for (auto _ : state) {
        add();
        benchmark::DoNotOptimize(estimate_relative_error(result));
    }
    state.SetBytesProcessed(int64_t(state.iterations()) * int64_t(4 * r.sum.size() * 8));
}

BENCHMARK(merge_fused)->Name("merge/fused")->Unit(benchmark::kMillisecond)->MinTime(2.0);
BENCHMARK(merge_add_then_estimate)
    ->Name("merge/add_then_estimate")
    ->Unit(benchmark::kMillisecond)
    ->MinTime(2.0);

}  // namespace
}  // namespace render::bench
