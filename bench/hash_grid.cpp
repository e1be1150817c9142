// The VCM hash grid per iteration (core/integrators/hash_grid.h) on the reference Cornell boxes
// at their reference resolution: building it over one iteration's light-subpath vertices (one
// light path per pixel, as VCM traces them) and querying it at one iteration's eye-subpath
// vertices, with the first iteration's merging radius (the largest: the most neighbours).
// Vertex positions come from subpaths traced in bench_scenes.cpp, not from random points.

#include <benchmark/benchmark.h>

#include <map>
#include <string>

#include "bench/bench_scenes.h"
#include "core/integrators/hash_grid.h"
#include "core/integrators/merge_radius.h"
#include "core/render/render_settings.h"

namespace render::bench {
namespace {

struct GridInput {
    std::vector<Vec3> light_vertices;
    std::vector<Vec3> eye_vertices;
    double radius = 0;
};

const GridInput& grid_input(const std::string& name) {
    static std::map<std::string, GridInput> inputs;
    auto it = inputs.find(name);
    if (it != inputs.end()) return it->second;
    const Scene& s = scene(name);
    const RenderSettings defaults;
    GridInput input;
    const uint64_t pixels = uint64_t(s.camera().width()) * uint64_t(s.camera().height());
    input.light_vertices = light_vertex_positions(s, pixels);
    input.eye_vertices = eye_vertex_positions(s);
    input.radius =
        merge_radius(defaults.radius_factor * s.bounding_sphere().radius, defaults.alpha, 1);
    return inputs.emplace(name, std::move(input)).first->second;
}

void build(benchmark::State& state, const std::string& name) {
    const GridInput& input = grid_input(name);
    for (auto _ : state) {
        HashGrid grid;  // VCM builds a fresh grid every iteration
        grid.build(input.light_vertices, input.radius);
        benchmark::DoNotOptimize(&grid);
    }
    state.counters["vertices"] = double(input.light_vertices.size());
    state.SetItemsProcessed(int64_t(state.iterations()) * int64_t(input.light_vertices.size()));
}

void query(benchmark::State& state, const std::string& name) {
    const GridInput& input = grid_input(name);
    HashGrid grid;
    grid.build(input.light_vertices, input.radius);
    uint64_t found = 0;
    for (auto _ : state) {
        uint64_t n = 0;
        for (const Vec3& p : input.eye_vertices)
            grid.for_each_within_radius(p, [&](uint32_t) { ++n; });
        benchmark::DoNotOptimize(n);
        found += n;
    }
    state.counters["queries"] = double(input.eye_vertices.size());
    state.counters["neighbours_per_query"] =
        double(found) / (double(state.iterations()) * double(input.eye_vertices.size()));
    state.SetItemsProcessed(int64_t(state.iterations()) * int64_t(input.eye_vertices.size()));
}

[[maybe_unused]] const bool registered = [] {
    for (const std::string& name : reference_scene_names()) {
        benchmark::RegisterBenchmark(("hash_grid/build/" + name).c_str(), build, name)
            ->Unit(benchmark::kMillisecond);
        benchmark::RegisterBenchmark(("hash_grid/query/" + name).c_str(), query, name)
            ->Unit(benchmark::kMillisecond);
    }
    return true;
}();

}  // namespace
}  // namespace render::bench
