// The photon-beam lookup of upbp (docs/design/media.md, "Photon beams in grid media": the figures):
// BeamsAlongRay (Embree user geometry, the default) against UniformBeamGrid (a uniform grid,
// SmallUPBP's kind of lookup), on one iteration's real photon beams (upbp at its defaults, one
// light path per pixel, short or long beams) of isosph and the smoke at 128 x 128. build: one
// iteration's build (the integrator rebuilds every iteration). query: every camera ray's
// pieces in media up to the first surface that is not a null boundary (the queries of the eye
// path's first segment), items = queries, so items/s is queries per second.

#include <benchmark/benchmark.h>

#include <map>
#include <memory>
#include <string>

#include "bench/bench_scenes.h"
#include "core/integrators/beam_grid.h"
#include "core/integrators/beams_along_ray.h"
#include "core/integrators/bidirectional/bidirectional_integrator.h"
#include "core/media/medium_interface.h"
#include "core/render/algorithms.h"
#include "core/render/render_options.h"
#include "core/scene/loader/scene_loader.h"

namespace render::bench {
namespace {

struct BeamInput {
    std::unique_ptr<Scene> scene;
    std::vector<BeamLine> beams;
    std::vector<Ray> queries;
    float radius = 0;
};

const BeamInput& beam_input(const std::string& name, bool long_beams) {
    static std::map<std::string, BeamInput> inputs;
    const std::string key = name + (long_beams ? "/long" : "/short");
    auto it = inputs.find(key);
    if (it != inputs.end()) return it->second;
    BeamInput in;
    in.scene = load_scene(scene_path(name).string(), {{"resx", "128"}, {"resy", "128"}});
    const Scene& s = *in.scene;
    RenderSettings settings = resolve_render_settings(
        "upbp", {{"photon_beam_length", long_beams ? "long" : "short"}}, s.settings);
    const std::unique_ptr<Integrator> integrator = make_integrator(settings);
    const auto& upbp = dynamic_cast<const BidirectionalIntegrator&>(*integrator);
    PhotonBeamInspection beams = upbp.inspect_photon_beams(s, IterationKey{7, 0, 1});
    in.beams = std::move(beams.lines);
    in.radius = float(beams.radius);
    // The first eye segment's query pieces, one jittered-free camera ray per pixel centre.
    const int w = s.camera().width(), h = s.camera().height();
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            Ray ray = s.camera().generate_ray(Vec2(float(x) + 0.5f, float(y) + 0.5f));
            const Medium* medium = s.camera_medium();
            for (int crossing = 0; crossing < 16; ++crossing) {
                SurfaceInteraction si;
                const bool hit = s.intersect(ray, si);
                if (medium) {
                    Ray q = ray;
                    q.t_max = hit ? si.t : kInfinity;
                    in.queries.push_back(q);
                }
                if (!hit || !si.bsdf->is_null()) break;
                medium = medium_after_surface(si, ray.direction, medium);
                ray = s.spawn_ray(si.p, si.geometric_normal, ray.direction);
            }
        }
    return inputs.emplace(key, std::move(in)).first->second;
}

void counters(benchmark::State& state, const BeamInput& in) {
    state.counters["beams"] = double(in.beams.size());
    state.counters["queries"] = double(in.queries.size());
}

void build_embree(benchmark::State& state, const std::string& name, bool long_beams) {
    const BeamInput& in = beam_input(name, long_beams);
    BeamsAlongRay lookup;  // the integrator keeps its device and rebuilds the scene
    for (auto _ : state) {
        lookup.build(in.beams, in.radius);
        benchmark::DoNotOptimize(&lookup);
    }
    counters(state, in);
}

void build_grid(benchmark::State& state, const std::string& name, bool long_beams) {
    const BeamInput& in = beam_input(name, long_beams);
    UniformBeamGrid grid;
    for (auto _ : state) {
        grid.build(in.beams, in.radius, in.scene->bounds());
        benchmark::DoNotOptimize(&grid);
    }
    counters(state, in);
    state.counters["references"] = double(grid.references());
}

template <typename Lookup>
void run_queries(benchmark::State& state, const BeamInput& in, const Lookup& lookup) {
    uint64_t found = 0;
    for (auto _ : state) {
        uint64_t n = 0;
        for (const Ray& q : in.queries)
            lookup.for_each_near(q, [&](uint32_t, const BeamApproach&) { ++n; });
        found = n;
        benchmark::DoNotOptimize(n);
    }
    counters(state, in);
    state.counters["found_per_query"] =
        in.queries.empty() ? 0.0 : double(found) / double(in.queries.size());
    state.SetItemsProcessed(int64_t(state.iterations()) * int64_t(in.queries.size()));
}

void query_embree(benchmark::State& state, const std::string& name, bool long_beams) {
    const BeamInput& in = beam_input(name, long_beams);
    BeamsAlongRay lookup;
    lookup.build(in.beams, in.radius);
    run_queries(state, in, lookup);
}

void query_grid(benchmark::State& state, const std::string& name, bool long_beams) {
    const BeamInput& in = beam_input(name, long_beams);
    UniformBeamGrid grid;
    grid.build(in.beams, in.radius, in.scene->bounds());
    run_queries(state, in, grid);
}

const bool registered = [] {
    for (const char* name : {"isosph", "smoke"})
        for (const bool long_beams : {false, true}) {
            const std::string suffix = std::string(name) + (long_beams ? "/long" : "/short");
            benchmark::RegisterBenchmark(("beams/build/embree/" + suffix).c_str(), build_embree,
                                         std::string(name), long_beams)
                ->Unit(benchmark::kMillisecond);
            benchmark::RegisterBenchmark(("beams/build/grid/" + suffix).c_str(), build_grid,
                                         std::string(name), long_beams)
                ->Unit(benchmark::kMillisecond);
            benchmark::RegisterBenchmark(("beams/query/embree/" + suffix).c_str(), query_embree,
                                         std::string(name), long_beams)
                ->Unit(benchmark::kMillisecond);
            benchmark::RegisterBenchmark(("beams/query/grid/" + suffix).c_str(), query_grid,
                                         std::string(name), long_beams)
                ->Unit(benchmark::kMillisecond);
        }
    return true;
}();

}  // namespace
}  // namespace render::bench
