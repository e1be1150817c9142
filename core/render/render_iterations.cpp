#include "core/render/render_iterations.h"

#include <tbb/global_control.h>
#include <tbb/task_arena.h>

#include <cmath>
#include <stdexcept>

#include "core/render/algorithms.h"

namespace render {

struct IterationRenderer::State {
    const Scene& scene;
    RenderSettings settings;
    uint32_t frame;
    std::unique_ptr<Integrator> integrator;
    AccumulationBuffer iteration_image;
    tbb::task_arena arena;

    State(const Scene& s, const RenderSettings& rs, uint32_t f)
        : scene(s),
          settings(rs),
          frame(f),
          integrator(make_integrator(rs)),
          iteration_image(s.camera().width(), s.camera().height()),
          arena(rs.threads > 0 ? rs.threads : tbb::task_arena::automatic) {}
};

IterationRenderer::IterationRenderer(const Scene& scene, const RenderSettings& settings,
                                     uint32_t frame)
    : state_(std::make_unique<State>(scene, settings, frame)) {
    check_algorithm_supports_scene(settings.algorithm, scene);
}

IterationRenderer::~IterationRenderer() = default;

IterationResult IterationRenderer::empty_result() const {
    const int width = state_->scene.camera().width(), height = state_->scene.camera().height();
    IterationResult result;
    result.sum = AccumulationBuffer(width, height);
    result.odd_sum = AccumulationBuffer(width, height);
    result.layers = TechniqueLayers(state_->settings.layers, width, height);
    return result;
}

void IterationRenderer::add(IterationRange range, IterationResult& result) {
    if (range.first < 1 || range.end <= range.first)
        throw std::invalid_argument("invalid iteration range [" + std::to_string(range.first) +
                                    ", " + std::to_string(range.end) + ")");
    State& s = *state_;
    AccumulationBuffer& image = s.iteration_image;
    s.arena.execute([&] {
        for (uint64_t i = range.first; i < range.end; ++i) {
            std::fill(image.values().begin(), image.values().end(), 0.0);
            // Layers are sums like the image; each pixel is written by one task per iteration,
            // so they accumulate directly.
            s.integrator->render_iteration(
                s.scene, IterationKey{s.settings.seed, s.frame, i}, image,
                result.layers.enabled() ? &result.layers : nullptr, result.stats);
            result.sum.add(image);
            if (i % 2 == 1) {
                result.odd_sum.add(image);
                ++result.odd_count;
            }
            ++result.count;
        }
    });
}

IterationResult render_iterations(const Scene& scene, const RenderSettings& settings,
                                  uint32_t frame, IterationRange range) {
    if (range.first < 1 || range.end <= range.first)
        throw std::invalid_argument("invalid iteration range [" + std::to_string(range.first) +
                                    ", " + std::to_string(range.end) + ")");
    IterationRenderer renderer(scene, settings, frame);
    IterationResult result = renderer.empty_result();
    renderer.add(range, result);
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
