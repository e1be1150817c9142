#pragma once

// The merged sums of one frame (double precision) and their checkpoint file. The checkpoint
// holds the buffers together with the ranges they contain, written atomically (temp + rename),
// so that after a crash buffers and ranges always agree.

#include <cstdint>
#include <filesystem>
#include <map>
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

    int width() const { return width_; }
    int height() const { return height_; }
    // Values per buffer (width * height * 3).
    size_t value_count() const { return size_t(width_) * height_ * 3; }

    // Per-technique layers merged with the sums (0 without).
    size_t layer_count() const { return result_.layers.size(); }

    // Adds one range's sums. `sum` and `odd_sum` must have value_count() entries,
    // `layer_sums` layer_count() * value_count() (the layers one after the other). For a range
    // of one iteration `odd_sum` may be empty: it is then `sum` when `odd_count` is 1 (an odd
    // iteration) and zero otherwise, exactly what the worker would have sent.
    void add(Range range, std::span<const double> sum, std::span<const double> odd_sum,
             std::span<const double> layer_sums, uint64_t odd_count, const RenderStats& stats);
    // The same from a received report's values (sum, odd_sum unless `odd_omitted`, then the
    // layers' sums), read block by block: a spooled report is never whole in memory. The sums
    // are the same, bit for bit, as from spans of the same values.
    void add(Range range, const ReportValues& values, bool odd_omitted, uint64_t odd_count,
             const RenderStats& stats);

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
    template <class Block>
    void add_blocks(Range range, bool odd_derived, uint64_t odd_count, const RenderStats& stats,
                    Block&& block);

    int width_ = 0, height_ = 0;
    IterationResult result_;
    IntervalSet ranges_;
    double relative_error_ = 1.0;
};

// Writes `image` (and `layers`) as EXR with the metadata through core (no OpenImageIO here).
void write_frame_exr(const std::filesystem::path& file, const Image& image,
                     const std::map<std::string, std::string>& metadata,
                     const std::vector<NamedLayer>& layers = {});

}  // namespace render::server
