#pragma once

// The merged sums of one frame (double precision) and their checkpoint file. The checkpoint
// holds the buffers together with the ranges they contain, written atomically (temp + rename),
// so that after a crash buffers and ranges always agree.

#include <cstdint>
#include <filesystem>
#include <map>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "core/render/render_iterations.h"
#include "server/interval_set.h"
#include "server/report_values.h"

namespace render::server {

class FrameAccumulator {
  public:
    // `layers`: the job's extra layers (its `layers` option): the per-technique sums or the
    // variance layers' sum of squares, merged like the sums.
    FrameAccumulator(int width, int height, LayerMode layers = LayerMode::None);
    // A job's frame: its layers, and for an adaptive job (settings.adaptive > 0) the exact sums,
    // each pixel's counts and the current round's mask (docs/reference/adaptive-sampling.md).
    FrameAccumulator(int width, int height, const RenderSettings& settings);

    int width() const { return width_; }
    int height() const { return height_; }
    // Values per buffer (width * height * 3).
    size_t value_count() const { return size_t(width_) * height_ * 3; }

    // Per-technique layers merged with the sums (0 without).
    size_t layer_count() const { return result_.layers.size(); }

    // Adds one range's sums. `sum` and `odd_sum` must have value_count() entries,
    // `layer_sums` layer_count() * value_count() (the layers one after the other). For a range
    // of one iteration `odd_sum` may be empty: it is then `sum` when `odd_count` is 1 (an odd
    // iteration) and zero otherwise, exactly what the worker would have sent. An adaptive
    // frame also takes the range's exact sums (one per pixel; `exact_odd` empty exactly when
    // `odd_sum` is), and the range must lie in the current round(): each pixel's counts follow
    // from its mask.
    void add(Range range, std::span<const double> sum, std::span<const double> odd_sum,
             std::span<const double> layer_sums, uint64_t odd_count, const RenderStats& stats,
             std::span<const int64_t> exact_sum = {}, std::span<const int64_t> exact_odd = {});
    // The same from a received report's values (sum, odd_sum unless `odd_omitted`, then the
    // layers' sums, then an adaptive frame's exact sums as int64 words), read block by block:
    // a spooled report is never whole in memory. The sums are the same, bit for bit, as from
    // spans of the same values.
    void add(Range range, const ReportValues& values, bool odd_omitted, uint64_t odd_count,
             const RenderStats& stats);
    // The number of values (8-byte words) a report of this frame carries, and the index where
    // its exact sums start (value_count() * (sums + layers)).
    size_t report_value_count(bool odd_omitted) const;
    size_t report_exact_at(bool odd_omitted) const;

    // --- adaptive sampling (an accumulator made with settings.adaptive > 0) ---
    bool adaptive() const { return rounds_.has_value(); }
    const AdaptiveRounds& rounds() const { return *rounds_; }
    // The round whose iterations are being merged, and its mask (1 = active; empty for round
    // 0, where every pixel is), packed as the worker protocol sends it (service/mask_bits.h),
    // its SHA-256 and its active pixels.
    uint64_t round() const { return round_; }
    const std::vector<uint8_t>& mask() const { return mask_; }
    const std::string& packed_mask() const { return packed_mask_; }
    const std::string& mask_sha256() const { return mask_sha256_; }
    uint64_t active_pixels() const { return active_pixels_; }
    // Whether the sums hold exactly the iterations before round() + 1 (its mask can be taken).
    bool round_complete() const;
    // The mask of round() + 1 from the merged exact sums (adaptive_round_mask; `settings` are
    // the job's); requires round_complete().
    std::vector<uint8_t> next_round_mask(const RenderSettings& settings) const;
    // Moves to round() + 1 with its mask (saved with the checkpoint from then on).
    void start_next_round(std::vector<uint8_t> mask);

    const IterationResult& result() const { return result_; }
    const IntervalSet& ranges() const { return ranges_; }
    uint64_t count() const { return result_.count; }
    // Estimated relative error of the current mean (1 when unknown): estimate_relative_error
    // of result(), computed by add() in its pass over the sums (and by load()), not per call.
    double relative_error() const { return relative_error_; }
    // The mean image so far (black when nothing is merged), and its extra layers as `render`
    // writes them (output_layers: the technique layers' means or the variance layers).
    Image average() const;
    std::vector<NamedLayer> layer_averages() const;

    // Writes the checkpoint atomically; throws std::runtime_error on I/O failure.
    void save(const std::filesystem::path& file, double elapsed_seconds) const;
    // Reads a checkpoint; throws std::runtime_error when it is missing, truncated or of
    // another size. `elapsed_seconds` receives the saved render time.
    static FrameAccumulator load(const std::filesystem::path& file, double* elapsed_seconds);

  private:
    // Both add()s: `block(offset, first, n)` gives values [first, first + n) of the part that
    // starts at `offset` in the report's sequence (sum at 0, odd_sum at value_count(), ...).
    // `exact(part, first, n, scratch)`: an adaptive frame's exact sums of pixels [first,
    // first + n), part 0 the sum, 1 the odd sum (asked only when the odd sum is not derived).
    template <class Block, class Exact>
    void add_blocks(Range range, bool odd_derived, uint64_t odd_count, const RenderStats& stats,
                    Block&& block, Exact&& exact);

    void set_mask(uint64_t round, std::vector<uint8_t> mask);

    int width_ = 0, height_ = 0;
    std::optional<AdaptiveRounds> rounds_;
    uint64_t round_ = 0;
    std::vector<uint8_t> mask_;
    std::string packed_mask_, mask_sha256_;
    uint64_t active_pixels_ = 0;
    IterationResult result_;
    IntervalSet ranges_;
    double relative_error_ = 1.0;
};

// Writes `image` (and `layers`) as EXR with the metadata through core (no OpenImageIO here).
void write_frame_exr(const std::filesystem::path& file, const Image& image,
                     const std::map<std::string, std::string>& metadata,
                     const std::vector<NamedLayer>& layers = {});

}  // namespace render::server
