#include "tests/support/block_estimate.h"

#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "core/render/render_iterations.h"
#include "tests/support/statistics.h"

namespace render::testing {

BlockEstimate render_block_estimate(const Scene& scene, const RenderSettings& settings, int batches,
                                    int iterations_per_batch, int blocks_per_side) {
    const int resolution = scene.camera().width();
    EXPECT_EQ(scene.camera().height(), resolution) << "the block test wants a square film";
    const int blocks = blocks_per_side * blocks_per_side, block_size = resolution / blocks_per_side;
    std::vector<std::vector<double>> batch_means(size_t(batches),
                                                 std::vector<double>(size_t(blocks) * 3, 0.0));
    for (int b = 0; b < batches; ++b) {
        const uint64_t first = 1 + uint64_t(b) * uint64_t(iterations_per_batch);
        const IterationResult r = render_iterations(
            scene, settings, 0, IterationRange{first, first + uint64_t(iterations_per_batch)});
        EXPECT_EQ(r.stats.non_finite, 0u) << settings.algorithm;
        for (int y = 0; y < resolution; ++y)
            for (int x = 0; x < resolution; ++x) {
                const int block = (y / block_size) * blocks_per_side + x / block_size;
                for (int c = 0; c < 3; ++c)
                    batch_means[size_t(b)][size_t(block) * 3 + size_t(c)] +=
                        r.sum.channel(size_t(y) * size_t(resolution) + size_t(x), c) /
                        (double(iterations_per_batch) * block_size * block_size);
            }
    }
    BlockEstimate e{std::vector<double>(size_t(blocks) * 3, 0.0),
                    std::vector<double>(size_t(blocks) * 3, 0.0)};
    for (size_t i = 0; i < e.mean.size(); ++i) {
        MeanAccumulator m;
        for (int b = 0; b < batches; ++b) m.add(batch_means[size_t(b)][i]);
        e.mean[i] = m.mean();
        e.standard_error[i] = m.standard_error();
    }
    return e;
}

std::vector<std::string> differing_blocks(const BlockEstimate& a, const BlockEstimate& b,
                                          double scale, double k,
                                          double noiseless_relative_tolerance) {
    std::vector<std::string> out;
    for (size_t i = 0; i < a.mean.size(); ++i) {
        const double se = std::hypot(a.standard_error[i], b.standard_error[i] * scale);
        const double d = a.mean[i] - b.mean[i] * scale;
        if (!(std::abs(d) <= k * se) &&
            !(se == 0 && std::abs(d) <= noiseless_relative_tolerance * std::abs(a.mean[i])))
            out.push_back("block " + std::to_string(i / 3) + " channel " + std::to_string(i % 3) +
                          ": " + std::to_string(a.mean[i]) + " vs " +
                          std::to_string(b.mean[i] * scale) + " (" + std::to_string(d / se) +
                          " standard errors)");
    }
    return out;
}

}  // namespace render::testing
