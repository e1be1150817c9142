// Seconds per iteration of every algorithm on the four reference Cornell boxes at their
// reference resolution (512 x 512, from the scene files), with 1 and 2 threads (volpt there
// measures what media-aware path tracing costs on a scene without media), and of volpt, bpt
// and vcm on the media scenes at their resolution with 2 threads. Each benchmark
// iteration is one progressive iteration rendered the way `render` and the worker render it:
// one IterationRenderer (one integrator, task arena and set of buffers for the frame), one
// iteration per call, with consecutive global iteration indices (the merging radius shrinks
// as in a real run). Iteration 1 is rendered before timing starts: it allocates the buffers
// that the following iterations reuse, a cost that a long render pays once. The figure is the
// wall-clock `real_time` of the JSON output (UseRealTime() is not set because it would append
// "/real_time" to the names that scripts/benchlib/performance.py parses).

#include <benchmark/benchmark.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <string>

#include "bench/bench_scenes.h"
#include "core/render/algorithms.h"
#include "core/render/render_iterations.h"
#include "core/render/render_options.h"

namespace render::bench {
namespace {

// On media scenes a representative subset (a path tracer, BPT, VCM), each where the algorithm
// table says it renders the scene's media; every physically based algorithm on the boxes.
const char* const kMediaAlgorithms[] = {"volpt", "bpt", "vcm"};

void iteration(benchmark::State& state, const std::string& name, const std::string& algorithm,
               int threads) {
    const Scene& s = scene(name);
    RenderSettings settings = resolve_render_settings(algorithm, {}, s.settings);
    settings.threads = threads;
    tbb::global_control control(tbb::global_control::max_allowed_parallelism, size_t(threads));
    IterationRenderer renderer(s, settings, 0);
    IterationResult result = renderer.empty_result();
    renderer.add(IterationRange{1, 2}, result);  // the warm-up iteration (see above)
    const RenderStats warm_up = result.stats;
    uint64_t i = 2;
    for (auto _ : state) {
        renderer.add(IterationRange{i, i + 1}, result);
        ++i;
    }
    benchmark::DoNotOptimize(result.sum.values().data());
    const uint64_t rays = result.stats.rays - warm_up.rays;
    const double n = double(state.iterations());
    state.counters["rays_per_iteration"] = double(rays) / n;
    state.counters["pixels"] = double(s.camera().width()) * double(s.camera().height());
}

[[maybe_unused]] const bool registered = [] {
    for (const std::string& name : reference_scene_names())
        for (const Algorithm& algorithm : algorithms()) {
            // The rows that name this suite (Algorithm::benchmarks), as the scripts read them.
            const auto& suites = algorithm.benchmarks;
            if (std::find(suites.begin(), suites.end(), "performance") == suites.end()) continue;
            for (int threads : {1, 2})
                benchmark::RegisterBenchmark(("iteration/" + name + "/" + algorithm.name +
                                              "/threads:" + std::to_string(threads))
                                                 .c_str(),
                                             iteration, name, algorithm.name, threads)
                    ->Unit(benchmark::kMillisecond);
        }
    // Media scenes at their own resolution, 2 threads (what media cost per iteration).
    for (const std::string& name : media_scene_names())
        for (const char* algorithm : kMediaAlgorithms) {
            try {
                check_algorithm_supports_scene(algorithm, scene(name));
            } catch (const std::invalid_argument&) {
                continue;  // e.g. the smoke's grid medium for the bidirectional family
            }
            benchmark::RegisterBenchmark(
                ("iteration/" + name + "/" + algorithm + "/threads:2").c_str(), iteration, name,
                std::string(algorithm), 2)
                ->Unit(benchmark::kMillisecond);
        }
    return true;
}();

}  // namespace
}  // namespace render::bench
