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
// them), `threads` as the renderer will run (0: every core of this machine).
IterationMemoryEstimate estimate_iteration_memory(const RenderSettings& settings, uint64_t width,
                                                  uint64_t height, int threads);

// Light vertices the estimate assumes a light path stores: its longest path when max_depth
// bounds it below that, else rr_depth plus kRouletteTailVertices (Russian roulette's tail: the
// mean number of vertices past rr_depth. From the measured peaks, the closed two-rooms scene
// stores ~5.5 vertices per path at rr_depth 5 and ~9.6 at 10: a tail of about 1; 4 is the
// margin. Closed scenes of albedo close to 1 can reach a tail of 19, which --max-depth bounds).
inline constexpr uint64_t kRouletteTailVertices = 4;
uint64_t assumed_light_vertices_per_path(const RenderSettings& settings);

}  // namespace render
