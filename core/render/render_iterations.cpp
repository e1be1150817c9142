#include "core/render/render_iterations.h"

#include <tbb/blocked_range.h>
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <cmath>
#include <stdexcept>

#include "core/image/variance_layers.h"
#include "core/render/algorithms.h"
#include "core/render/arena_invalid_ray_tally.h"

namespace render {
namespace {

// f(begin, end) over [0, n) in parallel ranges: for the element-wise passes over a frame's
// values, which give the same values whatever the split.
template <class F>
void for_each_range(size_t n, F&& f) {
    constexpr size_t kGrain = size_t(1) << 16;
    tbb::parallel_for(tbb::blocked_range<size_t>(0, n, kGrain),
                      [&](const tbb::blocked_range<size_t>& r) { f(r.begin(), r.end()); });
}

}  // namespace

struct IterationRenderer::State {
    const Scene& scene;
    RenderSettings settings;
    uint32_t frame;
    std::unique_ptr<Integrator> integrator;
    AccumulationBuffer iteration_image;
    tbb::task_arena arena;
    // The invalid rays of this render's threads alone (not the scene's count, which other
    // renders of the scene in the process add to).
    ArenaInvalidRayTally invalid_rays;

    State(const Scene& s, const RenderSettings& rs, uint32_t f)
        : scene(s),
          settings(rs),
          frame(f),
          integrator(make_integrator(rs)),
          iteration_image(s.camera().width(), s.camera().height()),
          arena(rs.threads > 0 ? rs.threads : tbb::task_arena::automatic),
          invalid_rays(arena) {}
};

IterationRenderer::IterationRenderer(const Scene& scene, const RenderSettings& settings,
                                     uint32_t frame)
    : state_(std::make_unique<State>(scene, settings, frame)) {
    check_algorithm_supports_scene(settings, scene);
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
    const uint64_t invalid_rays_before = s.invalid_rays.count();
    AccumulationBuffer& image = s.iteration_image;
    s.arena.execute([&] {
        std::vector<double>& values = image.values();
        std::vector<double>& sum = result.sum.values();
        std::vector<double>& odd_sum = result.odd_sum.values();
        for (uint64_t i = range.first; i < range.end; ++i) {
            for_each_range(values.size(), [&](size_t begin, size_t end) {
                std::fill(values.begin() + begin, values.begin() + end, 0.0);
            });
            // Layers are sums like the image; each pixel is written by one task per iteration,
            // so they accumulate directly.
            s.integrator->render_iteration(
                s.scene, IterationKey{s.settings.seed, s.frame, i}, image,
                result.layers.per_technique() ? &result.layers : nullptr, result.stats);
            const bool odd = i % 2 == 1;
            // The variance layers' sum of squares is a sum over iterations like the image's,
            // so it merges across ranges and workers the same way (docs/design/design.md).
            double* squares = result.layers.mode() == LayerMode::Variance
                                  ? result.layers.buffer(0).values().data()
                                  : nullptr;
            for_each_range(values.size(), [&](size_t begin, size_t end) {
                for (size_t k = begin; k < end; ++k) sum[k] += values[k];
                if (odd)
                    for (size_t k = begin; k < end; ++k) odd_sum[k] += values[k];
                if (squares)
                    for (size_t k = begin; k < end; ++k) squares[k] += values[k] * values[k];
            });
            if (odd) ++result.odd_count;
            ++result.count;
        }
    });
    result.stats.invalid_rays += s.invalid_rays.count() - invalid_rays_before;
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

std::vector<NamedLayer> output_layers(const IterationResult& result) {
    if (result.count == 0) return {};
    if (result.layers.mode() == LayerMode::Variance)
        return variance_layers(result.sum, result.odd_sum, result.layers.buffer(0), result.count,
                               result.odd_count);
    return result.layers.named_averages(result.count);
}

double estimate_relative_error(const IterationResult& result) {
    uint64_t even_count = result.count - result.odd_count;
    if (result.odd_count == 0 || even_count == 0) return 1.0;
    const auto& sum = result.sum.values();
    const auto& odd = result.odd_sum.values();
    RelativeErrorSums error(result.count, result.odd_count);
    for (size_t i = 0; i < sum.size(); ++i) error.add(sum[i], odd[i]);
    return error.relative_error();
}

}  // namespace render
