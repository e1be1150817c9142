#pragma once

// An up-front estimate of the memory an algorithm's iterations take besides the scene and the
// film: the light vertices of the bidirectional family and their merging grids,
// photon beams, the importance caches' tables and the per-thread buffers. It is computed from
// the settings alone, before anything is rendered, so that a worker (or `render
// --max-memory`) charges it to its SceneMemoryBudget and a job that would not fit fails with a
// message instead of the kernel killing the process. Calibration against measured peaks:
// docs/guide/reliability.md, "The memory budget" and "The algorithms' working memory per
// iteration".

#include <cstdint>
#include <string>

#include "core/render/render_settings.h"

namespace render {

struct IterationMemoryEstimate {
    uint64_t bytes = 0;
    // How the bytes were reckoned, for the budget's message: "vcm's working memory per
    // iteration (estimated 608.0 MiB: 2 threads x 4.0 MiB, 262144 light paths x ...)".
    std::string what;
};

// `settings` resolved (algorithm name or alias, max_depth and rr_depth as the render will use
// them), `threads` as the renderer will run (0: every core of this machine). The algorithm's own
// part comes from its row (Algorithm::iteration_memory); an unknown algorithm throws
// std::invalid_argument, as find_algorithm_or_throw does.
IterationMemoryEstimate estimate_iteration_memory(const RenderSettings& settings, uint64_t width,
                                                  uint64_t height, int threads);

// What an algorithm's row is given to estimate its working memory per iteration.
struct IterationMemoryInput {
    const RenderSettings& settings;
    uint64_t pixels = 0;
    uint64_t threads = 1;
    uint64_t light_vertices_per_path = 0;  // assumed_light_vertices_per_path(settings)
};

// The parts of an estimate, each charged with a few words on what it is.
struct IterationMemoryParts {
    uint64_t bytes = 0;
    std::string what;  // ", 262144 light paths x ..." per part
    std::string hint;  // what lowers the estimate, said last ("; fewer light paths ...")
    void add(uint64_t part_bytes, const std::string& text);
};

// The parts the algorithm rows are made of (core/render/algorithms.cpp).
// Stored light paths (the bidirectional family): their vertices with what each algorithm keeps
// beside them, and the light pass's chunks in flight.
struct LightPathStorage {
    bool merges = false;             // a merge index per vertex (ppm, bpm, vcm, upbp)
    bool volume_estimators = false;  // photon beams and the query beams' BVH (upbp)
    bool joint2_possible = false;    // J2's light rays and vertex states, when on (bpt)
};
void add_light_path_memory(const IterationMemoryInput& in, const LightPathStorage& storage,
                           IterationMemoryParts& parts);
// The VPLs of many-light rendering (vpl, ic), and the importance-driven distribution's records
// (vpl with it).
void add_vpl_memory(const IterationMemoryInput& in, bool importance_records,
                    IterationMemoryParts& parts);
// The importance caches' tables (ic, bpt --connections ic) over `cached_vertices` vertices.
void add_importance_cache_memory(const IterationMemoryInput& in, uint64_t cached_vertices,
                                 IterationMemoryParts& parts);

// Light vertices the estimate assumes a light path stores: its longest path when max_depth
// bounds it below that, else rr_depth plus kRouletteTailVertices (Russian roulette's tail: the
// mean number of vertices past rr_depth. From the measured peaks, the closed two-rooms scene
// stores ~5.5 vertices per path at rr_depth 5 and ~9.6 at 10: a tail of about 1; 4 is the
// margin. Closed scenes of albedo close to 1 can reach a tail of 19, which --max-depth bounds).
inline constexpr uint64_t kRouletteTailVertices = 4;
uint64_t assumed_light_vertices_per_path(const RenderSettings& settings);

}  // namespace render
