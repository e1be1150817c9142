// Ray queries: closest-hit and occlusion rays per second through Scene::intersect/occluded
// ("ours": Embree plus filling the SurfaceInteraction) and through bare rtcIntersect1 /
// rtcOccluded1 on the same RTCScene ("embree"), over the same precomputed rays (bench_scenes.h).
// The ratio of the two is the cost of our wrapper. For occlusion, "embree" is rtcOccluded1 on
// the closest-hit BVH, which holds every geometry; occluded() queries a BVH of its own, built
// without ROBUST, and tests up to four analytic shapes itself (core/scene/scene.h).

#include <benchmark/benchmark.h>
#include <embree3/rtcore.h>

#include <algorithm>
#include <span>
#include <string>
#include <vector>

#include "bench/bench_scenes.h"
#include "core/scene/embree_ray.h"

namespace render::bench {

// One pass of each closest-hit loop, out of line so that `performance.py`'s instruction count
// (valgrind --tool=callgrind --toggle-collect on these names) measures exactly the loop, per
// call, without the ray set-up or Google Benchmark around it.
[[gnu::noinline]] float trace_closest_ours(const Scene& s, const std::vector<Ray>& rays) {
    float sum = 0;
    for (const Ray& ray : rays) {
        // As the integrators' loops declare it: read only after a hit (interaction.h).
        SurfaceInteraction si(kUnfilled);
        if (s.intersect(ray, si)) sum += si.t + si.shading.n.x;
    }
    return sum;
}

[[gnu::noinline]] float trace_closest_embree(RTCScene rtc, const std::vector<Ray>& rays) {
    float sum = 0;
    for (const Ray& ray : rays) {
        // The same ray set-up as Scene::intersect (embree_ray.h), no interaction filled.
        RTCIntersectContext context;
        rtcInitIntersectContext(&context);
        RTCRayHit rh = to_rtc_ray_hit(ray);
        rtcIntersect1(rtc, &context, &rh);
        if (rh.hit.geomID != RTC_INVALID_GEOMETRY_ID) sum += rh.ray.tfar + rh.hit.Ng_x;
    }
    return sum;
}

namespace {

// The share of `rays` that this benchmark thread traces: with ->Threads(2) each thread takes
// its half (different rays on each core, as in a render); with one thread, all of them.
std::span<const Ray> thread_share(const benchmark::State& state, const std::vector<Ray>& rays) {
    const size_t threads = size_t(state.threads()), index = size_t(state.thread_index());
    const size_t begin = rays.size() * index / threads, end = rays.size() * (index + 1) / threads;
    return std::span<const Ray>(rays).subspan(begin, end - begin);
}

void closest_ours(benchmark::State& state, const std::string& name) {
    const Scene& s = scene(name);
    const std::vector<Ray>& rays = bench::rays(name).closest;
    for (auto _ : state) benchmark::DoNotOptimize(trace_closest_ours(s, rays));
    state.SetItemsProcessed(int64_t(state.iterations()) * int64_t(rays.size()));
}

void closest_embree(benchmark::State& state, const std::string& name) {
    const RTCScene rtc = scene(name).embree_scene();
    const std::vector<Ray>& rays = bench::rays(name).closest;
    for (auto _ : state) benchmark::DoNotOptimize(trace_closest_embree(rtc, rays));
    state.SetItemsProcessed(int64_t(state.iterations()) * int64_t(rays.size()));
}

void occluded_ours(benchmark::State& state, const std::string& name) {
    const Scene& s = scene(name);
    const std::span<const Ray> rays = thread_share(state, bench::rays(name).shadow);
    for (auto _ : state) {
        int blocked = 0;
        for (const Ray& ray : rays) blocked += s.occluded(ray) ? 1 : 0;
        benchmark::DoNotOptimize(blocked);
    }
    state.SetItemsProcessed(int64_t(state.iterations()) * int64_t(rays.size()));
}

void occluded_embree(benchmark::State& state, const std::string& name) {
    const RTCScene rtc = scene(name).embree_scene();
    const std::span<const Ray> rays = thread_share(state, bench::rays(name).shadow);
    for (auto _ : state) {
        int blocked = 0;
        for (const Ray& ray : rays) {
            RTCIntersectContext context;
            rtcInitIntersectContext(&context);
            RTCRay r = to_rtc_ray(ray);
            rtcOccluded1(rtc, &context, &r);
            blocked += r.tfar < 0 ? 1 : 0;
        }
        benchmark::DoNotOptimize(blocked);
    }
    state.SetItemsProcessed(int64_t(state.iterations()) * int64_t(rays.size()));
}

// The same shadow rays as occluded_embree, handed to Embree in batches of `batch` through the
// stream query rtcOccluded1M (incoherent: the shadow rays of connections and next-event
// estimation point every way). Whether batching pays is the question this case answers
// (docs/results/performance-notes.md, "Shadow rays in batches").
void occluded_embree_stream(benchmark::State& state, const std::string& name, int batch) {
    const RTCScene rtc = scene(name).embree_scene();
    const std::span<const Ray> rays = thread_share(state, bench::rays(name).shadow);
    std::vector<RTCRay> buffer(static_cast<size_t>(batch));
    for (auto _ : state) {
        int blocked = 0;
        for (size_t start = 0; start < rays.size(); start += size_t(batch)) {
            const size_t n = std::min(size_t(batch), rays.size() - start);
            for (size_t i = 0; i < n; ++i) buffer[i] = to_rtc_ray(rays[start + i]);
            RTCIntersectContext context;
            rtcInitIntersectContext(&context);
            context.flags = RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT;
            rtcOccluded1M(rtc, &context, buffer.data(), unsigned(n), sizeof(RTCRay));
            for (size_t i = 0; i < n; ++i) blocked += buffer[i].tfar < 0 ? 1 : 0;
        }
        benchmark::DoNotOptimize(blocked);
    }
    state.SetItemsProcessed(int64_t(state.iterations()) * int64_t(rays.size()));
}

// Scene::occluded for batches of `batch` rays (its own shadow BVH through rtcOccluded1M, the
// direct occluders per ray) against occluded_ours, one ray at a time on the same BVH: whether a
// path's few next-event rays (4) or a connection pass's many (16, 64) pay batched. Out of line
// under a name of its own, so that callgrind can count this loop alone.
[[gnu::noinline]] int trace_occluded_ours_batch(const Scene& s, std::span<const Ray> rays,
                                                int batch) {
    int blocked = 0;
    bool answers[256];
    for (size_t start = 0; start < rays.size(); start += size_t(batch)) {
        const size_t n = std::min(size_t(batch), rays.size() - start);
        s.occluded(rays.data() + start, n, answers);
        for (size_t i = 0; i < n; ++i) blocked += answers[i] ? 1 : 0;
    }
    return blocked;
}

[[gnu::noinline]] int trace_occluded_ours_single(const Scene& s, std::span<const Ray> rays) {
    int blocked = 0;
    for (const Ray& ray : rays) blocked += s.occluded(ray) ? 1 : 0;
    return blocked;
}

void occluded_ours_batch(benchmark::State& state, const std::string& name, int batch) {
    const Scene& s = scene(name);
    const std::span<const Ray> rays = thread_share(state, bench::rays(name).shadow);
    for (auto _ : state) benchmark::DoNotOptimize(trace_occluded_ours_batch(s, rays, batch));
    state.SetItemsProcessed(int64_t(state.iterations()) * int64_t(rays.size()));
}

void occluded_ours_single(benchmark::State& state, const std::string& name) {
    const Scene& s = scene(name);
    const std::span<const Ray> rays = thread_share(state, bench::rays(name).shadow);
    for (auto _ : state) benchmark::DoNotOptimize(trace_occluded_ours_single(s, rays));
    state.SetItemsProcessed(int64_t(state.iterations()) * int64_t(rays.size()));
}

[[maybe_unused]] const bool registered = [] {
    for (const std::string& name : ray_scene_names()) {
        benchmark::RegisterBenchmark(("rays/closest/ours/" + name).c_str(), closest_ours, name);
        benchmark::RegisterBenchmark(("rays/closest/embree/" + name).c_str(), closest_embree, name);
        benchmark::RegisterBenchmark(("rays/occluded/ours/" + name).c_str(), occluded_ours, name);
        benchmark::RegisterBenchmark(("rays/occluded/embree/" + name).c_str(), occluded_embree,
                                     name);
        for (int batch : {16, 64, 256})
            benchmark::RegisterBenchmark(
                ("rays/occluded/embree-stream" + std::to_string(batch) + "/" + name).c_str(),
                occluded_embree_stream, name, batch);
        // Scene::occluded one by one (out of line, for callgrind) and in batches.
        benchmark::RegisterBenchmark(("rays/occluded/ours-single/" + name).c_str(),
                                     occluded_ours_single, name);
        for (int batch : {4, 16, 64})
            benchmark::RegisterBenchmark(
                ("rays/occluded/ours-batch" + std::to_string(batch) + "/" + name).c_str(),
                occluded_ours_batch, name, batch);
        // Both cores at once, each thread on its half of the rays; rates per wall-clock second
        // of the pair (UseRealTime), so the 2-thread rate over the 1-thread one is the speed-up
        // and the stream's lead on two cores shows whether batching still pays when the cores
        // share the caches and the memory bus (docs/results/performance-notes.md, "Shadow rays
        // in batches").
        benchmark::RegisterBenchmark(("rays/occluded-2/ours/" + name).c_str(), occluded_ours, name)
            ->Threads(1)
            ->Threads(2)
            ->UseRealTime();
        benchmark::RegisterBenchmark(("rays/occluded-2/embree/" + name).c_str(), occluded_embree,
                                     name)
            ->Threads(1)
            ->Threads(2)
            ->UseRealTime();
        benchmark::RegisterBenchmark(("rays/occluded-2/embree-stream64/" + name).c_str(),
                                     occluded_embree_stream, name, 64)
            ->Threads(1)
            ->Threads(2)
            ->UseRealTime();
    }
    return true;
}();

}  // namespace
}  // namespace render::bench
