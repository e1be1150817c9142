#include "core/render/render_iterations.h"

#include <tbb/blocked_range.h>
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "core/image/variance_layers.h"
#include "core/integrators/integrator.h"
#include "core/render/algorithms.h"
#include "core/render/arena_invalid_ray_tally.h"

namespace render {
namespace {

// Brightness under which a pixel's error is taken relative to this value (as the mask's
// default, AdaptiveMaskSettings::dark): a black pixel's relative error is undefined.
constexpr double kPixelErrorDark = 1e-3;

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
    // Adaptive sampling: whether the integrator takes the masks, the rounds, and for
    // add_adaptive the mask of round `mask_round` (none yet: the largest value).
    bool takes_masks = false;
    AdaptiveRounds rounds;
    uint64_t mask_round = std::numeric_limits<uint64_t>::max();
    std::vector<uint8_t> mask;

    State(const Scene& s, const RenderSettings& rs, uint32_t f)
        : scene(s),
          settings(rs),
          frame(f),
          integrator(make_integrator(rs)),
          iteration_image(s.camera().width(), s.camera().height()),
          arena(rs.threads > 0 ? rs.threads : tbb::task_arena::automatic),
          invalid_rays(arena),
          rounds(rs) {}
};

IterationRenderer::IterationRenderer(const Scene& scene, const RenderSettings& settings,
                                     uint32_t frame)
    : state_(std::make_unique<State>(scene, settings, frame)) {
    check_algorithm_supports_scene(settings, scene);
    if (settings.adaptive > 0) {
        // Only an integrator that can skip a pixel without changing the others' values takes
        // a mask (docs/reference/adaptive-sampling.md, "Algorithms").
        state_->takes_masks = state_->integrator->takes_active_pixels();
        if (!state_->takes_masks)
            throw std::invalid_argument(
                "adaptive sampling (--adaptive) is supported by pt, volpt and the bidirectional "
                "and many-light families, not by " +
                settings.algorithm);
        if (settings.layers != LayerMode::None)
            throw std::invalid_argument(
                "adaptive sampling (--adaptive) writes its own layer (samples); --layers is "
                "not supported with it");
        if (settings.adaptive_min_iterations < 2 || settings.adaptive_round < 1)
            throw std::invalid_argument(
                "adaptive sampling needs --adaptive-min-iterations >= 2 (both halves of every "
                "pixel's error estimate) and --adaptive-round >= 1");
    }
}

IterationRenderer::~IterationRenderer() = default;

IterationResult IterationRenderer::empty_result() const {
    const int width = state_->scene.camera().width(), height = state_->scene.camera().height();
    IterationResult result;
    result.sum = AccumulationBuffer(width, height);
    result.odd_sum = AccumulationBuffer(width, height);
    result.layers = TechniqueLayers(state_->settings.layers, width, height);
    if (state_->settings.adaptive > 0) result.adaptive = AdaptiveSums(size_t(width) * height);
    return result;
}

void IterationRenderer::add(IterationRange range, IterationResult& result,
                            std::span<const uint8_t> active) {
    if (range.first < 1 || range.end <= range.first)
        throw std::invalid_argument("invalid iteration range [" + std::to_string(range.first) +
                                    ", " + std::to_string(range.end) + ")");
    State& s = *state_;
    const bool adaptive = s.settings.adaptive > 0;
    if (adaptive) {
        const uint64_t round = s.rounds.round_of(range.first);
        if (s.rounds.round_of(range.end - 1) != round)
            throw std::invalid_argument("adaptive sampling: iteration range [" +
                                        std::to_string(range.first) + ", " +
                                        std::to_string(range.end) + ") spans two rounds");
        if (round > 0 && active.size() != result.adaptive.count.size())
            throw std::invalid_argument("adaptive sampling: iterations after the first " +
                                        std::to_string(s.settings.adaptive_min_iterations) +
                                        " need their round's mask");
        if (result.adaptive.empty())
            throw std::invalid_argument("adaptive sampling: a result without adaptive sums");
        if (round == 0) active = {};
    } else if (!active.empty()) {
        throw std::invalid_argument("an active-pixel mask for a job that is not adaptive");
    }
    if (s.takes_masks) s.integrator->set_active_pixels(active.empty() ? nullptr : active.data());
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
            if (adaptive) result.adaptive.add_iteration(values, i, active);
            if (odd) ++result.odd_count;
            ++result.count;
        }
    });
    if (s.takes_masks) s.integrator->set_active_pixels(nullptr);
    result.stats.invalid_rays += s.invalid_rays.count() - invalid_rays_before;
}

const std::vector<uint8_t>& IterationRenderer::adaptive_mask_for(uint64_t iteration,
                                                                 const IterationResult& result) {
    State& s = *state_;
    if (s.settings.adaptive <= 0 || result.adaptive.empty())
        throw std::invalid_argument("add_adaptive: the job is not adaptive");
    if (result.count != iteration - 1)
        throw std::invalid_argument("add_adaptive: the result must hold exactly iterations [1, " +
                                    std::to_string(iteration) + ")");
    const uint64_t round = s.rounds.round_of(iteration);
    if (round != s.mask_round) {
        if (round > 0 && iteration != s.rounds.first(round))
            throw std::invalid_argument(
                "add_adaptive: a round's mask is taken at its first iteration");
        const int width = s.scene.camera().width(), height = s.scene.camera().height();
        s.mask = round == 0 ? std::vector<uint8_t>(size_t(width) * height, 1)
                            : adaptive_round_mask(result.adaptive, width, height, s.settings);
        s.mask_round = round;
    }
    return s.mask;
}

void IterationRenderer::add_adaptive(IterationRange range, IterationResult& result) {
    for (uint64_t first = range.first; first < range.end;) {
        const uint64_t round = state_->rounds.round_of(first);
        const uint64_t end = std::min(range.end, state_->rounds.end(round));
        const std::vector<uint8_t>& mask = adaptive_mask_for(first, result);
        add({first, end}, result, round == 0 ? std::span<const uint8_t>() : std::span(mask));
        first = end;
    }
}

uint64_t IterationRenderer::adaptive_active_pixels(const IterationResult& result) {
    const std::vector<uint8_t>& mask = adaptive_mask_for(result.count + 1, result);
    uint64_t active = 0;
    for (uint8_t m : mask) active += m;
    return active;
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

Image mean_image(const IterationResult& result) {
    if (result.adaptive.empty()) return result.sum.average(double(result.count));
    Image image(result.sum.width(), result.sum.height());
    for (size_t p = 0; p < image.pixel_count(); ++p) {
        const uint64_t n = result.adaptive.count[p];
        const double scale = n > 0 ? 1.0 / double(n) : 0.0;
        image.set(
            p, Rgb(float(result.sum.channel(p, 0) * scale), float(result.sum.channel(p, 1) * scale),
                   float(result.sum.channel(p, 2) * scale)));
    }
    return image;
}

std::vector<NamedLayer> output_layers(const IterationResult& result) {
    if (result.count == 0) return {};
    if (!result.adaptive.empty()) {
        Image samples(result.sum.width(), result.sum.height());
        for (size_t p = 0; p < samples.pixel_count(); ++p) {
            const float n = float(result.adaptive.count[p]);
            samples.set(p, Rgb(n, n, n));
        }
        return {NamedLayer{"samples", std::move(samples)}};
    }
    if (result.layers.mode() == LayerMode::Variance)
        return variance_layers(result.sum, result.odd_sum, result.layers.buffer(0), result.count,
                               result.odd_count);
    return result.layers.named_averages(result.count);
}

double estimate_relative_error(const IterationResult& result) {
    if (!result.adaptive.empty()) {
        // Each pixel's halves and mean with its own counts, summed over the image like the
        // uniform figure's.
        const auto& sum = result.sum.values();
        const auto& odd = result.odd_sum.values();
        RelativeErrorSums error;
        for (size_t p = 0; p < result.adaptive.count.size(); ++p) {
            const uint64_t n = result.adaptive.count[p], n_odd = result.adaptive.odd_count[p];
            if (n_odd == 0 || n_odd >= n) return 1.0;
            for (size_t c = 3 * p; c < 3 * p + 3; ++c) error.add_pixel(sum[c], odd[c], n, n_odd);
        }
        return error.relative_error();
    }
    uint64_t even_count = result.count - result.odd_count;
    if (result.odd_count == 0 || even_count == 0) return 1.0;
    const auto& sum = result.sum.values();
    const auto& odd = result.odd_sum.values();
    RelativeErrorSums error(result.count, result.odd_count);
    for (size_t i = 0; i < sum.size(); ++i) error.add(sum[i], odd[i]);
    return error.relative_error();
}

std::vector<double> estimate_pixel_relative_errors(const IterationResult& result) {
    if (result.count == 0) return {};
    const int width = result.sum.width(), height = result.sum.height();
    const size_t pixels = size_t(width) * size_t(height);
    const bool adaptive = !result.adaptive.empty();
    std::vector<double> own(pixels);
    for (size_t p = 0; p < pixels; ++p) {
        const uint64_t n = adaptive ? result.adaptive.count[p] : result.count;
        const uint64_t n_odd = adaptive ? result.adaptive.odd_count[p] : result.odd_count;
        double s = 0, o = 0;
        for (int c = 0; c < 3; ++c) {
            s += result.sum.channel(p, c);
            o += result.odd_sum.channel(p, c);
        }
        own[p] = halves_relative_error(s, o, n, n_odd, kPixelErrorDark);
    }
    std::vector<double> error(pixels);
    for (int y = 0; y < height; ++y)
        for (int x = 0; x < width; ++x) {
            double squares = 0;
            int n = 0;
            for (int yy = std::max(0, y - 1); yy <= std::min(height - 1, y + 1); ++yy)
                for (int xx = std::max(0, x - 1); xx <= std::min(width - 1, x + 1); ++xx) {
                    const double e = own[size_t(yy) * width + xx];
                    squares += e * e;
                    ++n;
                }
            error[size_t(y) * width + x] = std::sqrt(squares / n);
        }
    return error;
}

double max_pixel_relative_error(const IterationResult& result) {
    const std::vector<double> errors = estimate_pixel_relative_errors(result);
    if (errors.empty()) return std::numeric_limits<double>::infinity();
    return *std::max_element(errors.begin(), errors.end());
}

}  // namespace render
