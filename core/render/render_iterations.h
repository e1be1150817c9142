#pragma once

// The one entry point through which every image is rendered (DESIGN.md, iteration contract):
// a pure function of (scene, settings, frame, [first, end)).

#include <cmath>
#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include "core/image/image.h"
#include "core/image/technique_layers.h"
#include "core/render/adaptive_rounds.h"
#include "core/render/render_settings.h"
#include "core/scene/scene.h"

namespace render {

struct IterationRange {
    uint64_t first = 1;  // 1-based global iteration index, inclusive
    uint64_t end = 2;    // exclusive
};

struct IterationResult {
    AccumulationBuffer sum;      // sum of the iterations' images
    AccumulationBuffer odd_sum;  // sum over the odd iterations only (noise estimation)
    uint64_t count = 0;          // iterations rendered
    uint64_t odd_count = 0;      // odd-indexed iterations among them
    TechniqueLayers layers;      // per-technique sums or the sum of squares (settings.layers)
    // Adaptive sampling's exact sums and per-pixel counts (settings.adaptive > 0; else empty).
    // With them a pixel's mean is its sum over its own count, and `count` stays the number of
    // global iterations merged.
    AdaptiveSums adaptive;
    RenderStats stats;
};

// Renders iterations [first, end) and returns their sum. The result is the same, up to float
// summation order, however the range is split and however many threads run it.
// Throws std::invalid_argument for an unknown algorithm or an empty/invalid range.
IterationResult render_iterations(const Scene& scene, const RenderSettings& settings,
                                  uint32_t frame, IterationRange range);

class Integrator;

// The same, for callers that render a frame a few iterations at a time (render's progress bar
// and time budget, a worker's cancellation between iterations): the integrator, the thread
// arena and the per-iteration image are made once, and each call adds to the caller's result,
// so no call allocates a full-frame buffer (per-call buffers cost page faults every
// iteration). add(r1), add(r2) gives exactly what render_iterations over r1 then r2 adds.
class IterationRenderer {
  public:
    // Throws as render_iterations does for an unknown algorithm or an unsupported scene.
    IterationRenderer(const Scene& scene, const RenderSettings& settings, uint32_t frame);
    ~IterationRenderer();
    IterationRenderer(const IterationRenderer&) = delete;
    IterationRenderer& operator=(const IterationRenderer&) = delete;

    // An empty result with the frame's buffers (and layers, if the settings ask for them).
    IterationResult empty_result() const;
    // Renders `range` and adds it to `result` (made by empty_result()). For an adaptive job
    // the range lies within one round (AdaptiveRounds) and `active` is that round's mask (one
    // entry per pixel), given by whoever merged every iteration before the round (the server,
    // or add_adaptive); empty for round 0, where every pixel is active.
    void add(IterationRange range, IterationResult& result, std::span<const uint8_t> active = {});

    // An adaptive job rendered in one process (`render`): `result` holds exactly iterations
    // [1, range.first), and each round's mask is computed from it at the round's first
    // iteration. The same image as any split of the job over workers whose masks come from
    // the merged sums (docs/reference/adaptive-sampling.md).
    void add_adaptive(IterationRange range, IterationResult& result);
    // The active pixels of iteration result.count + 1 of an adaptive job rendered by
    // add_adaptive (its mask computed, if it starts a round): 0 when every pixel has converged.
    uint64_t adaptive_active_pixels(const IterationResult& result);

  private:
    const std::vector<uint8_t>& adaptive_mask_for(uint64_t iteration,
                                                  const IterationResult& result);
    struct State;
    std::unique_ptr<State> state_;
};

// The image of a result: its sum over the iteration count, or over each pixel's own count for an
// adaptive job (a pixel that never took an iteration is black).
Image mean_image(const IterationResult& result);

// The extra EXR layers of a result, as `render` and the server write them: the per-technique
// layers' means, or for LayerMode::Variance the per-pixel error layers (variance_layers: the
// variance of each pixel's mean and the odd and even half images); for an adaptive job the layer
// "samples", each pixel's iteration count in R, G and B. None before any iteration.
std::vector<NamedLayer> output_layers(const IterationResult& result);

// The sums behind estimate_relative_error, pixel value by pixel value: the means of odd and even
// iterations, whose difference has variance ~ 4 var(mean) for equal halves. Either every value
// shares one count (`sum` over all `count` iterations, `odd` over the `odd_count` odd ones; both
// must be > 0 and odd_count < count; the server takes them in the pass that adds a report,
// server/accumulator.cpp), or each value comes with its pixel's own counts (adaptive sampling).
class RelativeErrorSums {
  public:
    RelativeErrorSums(uint64_t count, uint64_t odd_count)
        : n_odd_(double(odd_count)), n_even_(double(count - odd_count)), n_(double(count)) {}
    // For values with their own counts (add_pixel only).
    RelativeErrorSums() = default;
    void add(double sum, double odd) {
        const double mean_odd = odd / n_odd_, mean_even = (sum - odd) / n_even_;
        const double mean = sum / n_;
        diff2_ += (mean_odd - mean_even) * (mean_odd - mean_even);
        mean2_ += mean * mean;
    }
    // A value over its pixel's `count` iterations, `odd_count` of them odd (both halves non-empty):
    // the mean's variance is var (1/n_o + 1/n_e) n_o n_e / n^2 of the halves' difference's.
    void add_pixel(double sum, double odd, uint64_t count, uint64_t odd_count) {
        const double n = double(count), n_odd = double(odd_count),
                     n_even = double(count - odd_count);
        const double diff = odd / n_odd - (sum - odd) / n_even, mean = sum / n;
        weighted_diff2_ += diff * diff * n_odd * n_even / (n * n);
        mean2_ += mean * mean;
    }
    // The full mean's error is half the half-means' difference (two independent halves).
    double relative_error() const {
        if (mean2_ <= 0) return 0.0;
        return n_ > 0 ? 0.5 * std::sqrt(diff2_ / mean2_) : std::sqrt(weighted_diff2_ / mean2_);
    }

  private:
    double n_odd_ = 0, n_even_ = 0, n_ = 0;
    double diff2_ = 0, weighted_diff2_ = 0, mean2_ = 0;
};

// Estimated relative error of the mean image from the even/odd half sums: the RMS of the
// difference of the two half means over the RMS of the full mean (0 if black). For an adaptive
// job each pixel's halves and mean use its own counts.
double estimate_relative_error(const IterationResult& result);

// Each pixel's estimated relative error (--target-error per pixel,
// docs/reference/adaptive-sampling.md): the root mean square, over the pixel's 3 x 3
// neighbourhood clipped at the frame's edge, of the pixels' relative errors of their mean
// brightness R + G + B (halves_relative_error: the odd/even halves' standard error over
// max(mean, 1e-3)), each with its own counts for an adaptive job. One pixel's own estimate has
// one degree of freedom, the window's nine. Infinity where a pixel in the window has an empty
// half (the error is unknown); empty before any iteration.
std::vector<double> estimate_pixel_relative_errors(const IterationResult& result);
// The largest of them (infinity when unknown): every pixel's estimate is at most this.
double max_pixel_relative_error(const IterationResult& result);

}  // namespace render
