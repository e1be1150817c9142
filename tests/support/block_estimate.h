#pragma once

// The block test's estimate (tests/unit/render/convergence_test.cpp, pbrt_scenes_test.cpp): an
// image rendered in `batches` consecutive batches of iterations, cut into blocks_per_side^2 square
// blocks; per block and channel the mean over the batches and its standard error from the
// spread of the batch means (batches - 1 degrees of freedom).

#include <string>
#include <vector>

#include "core/render/render_settings.h"
#include "core/scene/scene.h"

namespace render::testing {

struct BlockEstimate {
    std::vector<double> mean;            // [block * 3 + channel]
    std::vector<double> standard_error;  // of the mean
};

// Batch b renders iterations [1 + b n, 1 + (b + 1) n) with n = iterations_per_batch, so the
// estimate is that of one render of batches x n iterations. The scene's film must be square
// with a side divisible by blocks_per_side. Non-finite samples fail the calling test.
BlockEstimate render_block_estimate(const Scene& scene, const RenderSettings& settings, int batches,
                                    int iterations_per_batch, int blocks_per_side);

// The blocks and channels where a and b * scale differ by more than k combined standard errors,
// each described for a failure message ("block 3 channel 1: ... (6.2 standard errors)"). A block
// whose combined standard error is 0 (it sees no noise, e.g. only a constant environment) may
// differ by at most noiseless_relative_tolerance of a's mean there.
std::vector<std::string> differing_blocks(const BlockEstimate& a, const BlockEstimate& b,
                                          double scale, double k,
                                          double noiseless_relative_tolerance = 0.0);

}  // namespace render::testing
