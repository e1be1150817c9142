#include "core/render/render_iterations.h"

#include <tbb/global_control.h>
#include <tbb/task_arena.h>

#include <cmath>
#include <stdexcept>

#include "core/render/algorithms.h"

namespace render {

IterationResult render_iterations(const Scene& scene, const RenderSettings& settings,
                                  uint32_t frame, IterationRange range) {
    if (range.first < 1 || range.end <= range.first)
        throw std::invalid_argument("invalid iteration range [" + std::to_string(range.first) +
                                    ", " + std::to_string(range.end) + ")");
    std::unique_ptr<Integrator> integrator = make_integrator(settings);
    check_algorithm_supports_scene(settings.algorithm, scene);
    const int width = scene.camera().width(), height = scene.camera().height();
    IterationResult result;
    result.sum = AccumulationBuffer(width, height);
    result.odd_sum = AccumulationBuffer(width, height);
    result.layers = TechniqueLayers(settings.layers, width, height);
    AccumulationBuffer iteration_image(width, height);
    tbb::task_arena arena(settings.threads > 0 ? settings.threads : tbb::task_arena::automatic);
    arena.execute([&] {
        for (uint64_t i = range.first; i < range.end; ++i) {
            std::fill(iteration_image.values().begin(), iteration_image.values().end(), 0.0);
            // Layers are sums like the image; each pixel is written by one task per iteration,
            // so they accumulate directly.
            integrator->render_iteration(
                scene, IterationKey{settings.seed, frame, i}, iteration_image,
                result.layers.enabled() ? &result.layers : nullptr, result.stats);
            result.sum.add(iteration_image);
            if (i % 2 == 1) {
                result.odd_sum.add(iteration_image);
                ++result.odd_count;
            }
            ++result.count;
        }
    });
    return result;
}

double estimate_relative_error(const IterationResult& result) {
    uint64_t even_count = result.count - result.odd_count;
    if (result.odd_count == 0 || even_count == 0) return 1.0;
    // Means of odd and even iterations; their difference has variance ~ 4 var(mean).
    const auto& sum = result.sum.values();
    const auto& odd = result.odd_sum.values();
    double n_odd = double(result.odd_count), n_even = double(even_count);
    double diff2 = 0, mean2 = 0;
    for (size_t i = 0; i < sum.size(); ++i) {
        double mean_odd = odd[i] / n_odd, mean_even = (sum[i] - odd[i]) / n_even;
        double mean = sum[i] / double(result.count);
        diff2 += (mean_odd - mean_even) * (mean_odd - mean_even);
        mean2 += mean * mean;
    }
    if (mean2 <= 0) return 0.0;
    // The full mean's error is half the half-means' difference (two independent halves).
    return 0.5 * std::sqrt(diff2 / mean2);
}

}  // namespace render
