#include "server/accumulator.h"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <stdexcept>
#include <utility>

#include "core/image/exr_io.h"
#include "core/util/log.h"
#include "core/util/sha256.h"
#include "server/write_all.h"
#include "service/mask_bits.h"

namespace render::server {

namespace {

// Version 2 adds the VPL counters, the layer mode and the layers' sums after odd_sum; version 1
// files (no layers) are still read. The variance layers' sum of squares is one such layer
// (LayerMode::Variance), so a job without them saves no more than before. Version 3, written
// for adaptive frames only, is version 2 plus the rounds (their first boundaries), the current
// round and, after the layers, the exact sums, each pixel's counts and the round's mask: the
// mask of a round cannot be computed again from the later sums (adaptive-sampling.md).
constexpr char kMagic[8] = {'R', 'C', 'K', 'P', '0', '0', '0', '2'};
constexpr char kMagicVersion1[8] = {'R', 'C', 'K', 'P', '0', '0', '0', '1'};
constexpr char kMagicAdaptive[8] = {'R', 'C', 'K', 'P', '0', '0', '0', '3'};

template <typename T>
void put(std::string& out, const T& v) {
    out.append(reinterpret_cast<const char*>(&v), sizeof v);
}

template <typename T>
void get(std::ifstream& in, T& v, const std::filesystem::path& file) {
    if (!in.read(reinterpret_cast<char*>(&v), sizeof v))
        throw std::runtime_error("checkpoint " + file.string() + " is truncated");
}

void write_all(int fd, const char* data, size_t size, const std::filesystem::path& file) {
    if (!server::write_all(fd, data, size))
        throw std::runtime_error("cannot write " + file.string() + ": " + std::strerror(errno));
}

}  // namespace

FrameAccumulator::FrameAccumulator(int width, int height, LayerMode layers)
    : width_(width), height_(height) {
    result_.sum = AccumulationBuffer(width, height);
    result_.odd_sum = AccumulationBuffer(width, height);
    // TechniqueLayers(mode, w, h) fills its layers from a temporary frame-sized buffer, made
    // even when there are none: at a 4K frame's first report that was a fourth buffer of a
    // frame's values beside the sums and the report (a peak of 2x the sums for one-iteration
    // reports). A job without layers keeps the empty default.
    if (layers != LayerMode::None) result_.layers = TechniqueLayers(layers, width, height);
}

FrameAccumulator::FrameAccumulator(int width, int height, const RenderSettings& settings)
    : FrameAccumulator(width, height, settings.layers) {
    if (settings.adaptive > 0) {
        rounds_.emplace(settings);
        result_.adaptive = AdaptiveSums(size_t(width) * size_t(height));
    }
}

void FrameAccumulator::set_mask(uint64_t round, std::vector<uint8_t> mask) {
    round_ = round;
    mask_ = std::move(mask);
    packed_mask_ = round == 0 ? std::string() : service::pack_mask(mask_);
    mask_sha256_ = round == 0 ? std::string() : sha256_hex(packed_mask_);
    active_pixels_ = round == 0 ? uint64_t(width_) * uint64_t(height_) : 0;
    if (round > 0)
        for (uint8_t m : mask_) active_pixels_ += m;
}

bool FrameAccumulator::round_complete() const {
    if (!rounds_) return false;
    const uint64_t end = rounds_->end(round_);
    return result_.count == end - 1 && ranges_.contains({1, end});
}

std::vector<uint8_t> FrameAccumulator::next_round_mask(const RenderSettings& settings) const {
    if (!round_complete())
        throw std::logic_error("next_round_mask: the round's iterations are not all merged");
    return adaptive_round_mask(result_.adaptive, width_, height_, settings);
}

void FrameAccumulator::start_next_round(std::vector<uint8_t> mask) {
    if (!round_complete() || mask.size() != size_t(width_) * size_t(height_))
        throw std::logic_error("start_next_round: the round is not complete or the mask's size");
    set_mask(round_ + 1, std::move(mask));
}

size_t FrameAccumulator::report_exact_at(bool odd_omitted) const {
    return ((odd_omitted ? 1 : 2) + layer_count()) * value_count();
}

size_t FrameAccumulator::report_value_count(bool odd_omitted) const {
    const size_t pixels = size_t(width_) * size_t(height_);
    return report_exact_at(odd_omitted) + (rounds_ ? (odd_omitted ? 1 : 2) * pixels : 0);
}

namespace {

// Values per block when a report is added block by block: 1 MiB per part read.
constexpr size_t kBlockValues = size_t(1) << 17;

}  // namespace

template <class Block, class Exact>
void FrameAccumulator::add_blocks(Range range, bool odd_derived, uint64_t odd_count,
                                  const RenderStats& stats, Block&& block, Exact&& exact) {
    if (rounds_ &&
        (rounds_->round_of(range.first) != round_ || rounds_->round_of(range.end - 1) != round_))
        throw std::invalid_argument("accumulator: range [" + std::to_string(range.first) + ", " +
                                    std::to_string(range.end) + ") is not in round " +
                                    std::to_string(round_));
    const size_t n = value_count();
    double* s = result_.sum.values().data();
    double* o = result_.odd_sum.values().data();
    const uint64_t count = result_.count + range.size();
    const uint64_t odds = result_.odd_count + odd_count;
    // The relative error (1 while the odd or the even iterations are none) is estimated in
    // the addition's pass: the same sums in the same order as estimate_relative_error.
    // An adaptive frame's pixels have counts of their own: estimated after the addition.
    const bool estimate = odds != 0 && odds != count && !rounds_;
    RelativeErrorSums error(count, odds);
    // One pass per block: `update(i)` adds value i and returns the new sum and odd sum.
    auto pass = [&](size_t m, auto&& update) {
        if (!estimate) {
            for (size_t i = 0; i < m; ++i) update(i);
            return;
        }
        for (size_t i = 0; i < m; ++i) {
            const auto [sum, odd] = update(i);
            error.add(sum, odd);
        }
    };
    using Pair = std::pair<double, double>;
    for (size_t first = 0; first < n; first += kBlockValues) {
        const size_t m = std::min(kBlockValues, n - first);
        const double* sum = block(0, first, m).data();
        double* sb = s + first;
        double* ob = o + first;
        if (!odd_derived) {
            const double* odd = block(n, first, m).data();
            pass(m, [&](size_t i) {
                sb[i] += sum[i];
                ob[i] += odd[i];
                return Pair{sb[i], ob[i]};
            });
        } else if (odd_count == 1) {
            pass(m, [&](size_t i) {
                sb[i] += sum[i];
                ob[i] += sum[i];
                return Pair{sb[i], ob[i]};
            });
        } else {
            pass(m, [&](size_t i) {
                sb[i] += sum[i];
                return Pair{sb[i], ob[i]};
            });
        }
    }
    relative_error_ = estimate ? error.relative_error() : 1.0;
    const size_t layers_at = (odd_derived ? 1 : 2) * n;
    for (size_t l = 0; l < layer_count(); ++l) {
        double* values = result_.layers.buffer(l).values().data();
        for (size_t first = 0; first < n; first += kBlockValues) {
            const size_t m = std::min(kBlockValues, n - first);
            const double* add = block(layers_at + l * n, first, m).data();
            for (size_t i = 0; i < m; ++i) values[first + i] += add[i];
        }
    }
    if (rounds_) {
        // The exact sums (an odd sum omitted with odd_sum is the sum for one odd iteration,
        // zero for an even one) and the counts the round's mask gives.
        const size_t pixels = size_t(width_) * size_t(height_);
        std::vector<int64_t> scratch_sum, scratch_odd;
        for (size_t first = 0; first < pixels; first += kBlockValues) {
            const size_t m = std::min(kBlockValues, pixels - first);
            const std::span<const int64_t> sum = exact(0, first, m, scratch_sum);
            std::span<const int64_t> odd;
            if (!odd_derived)
                odd = exact(1, first, m, scratch_odd);
            else if (odd_count == 1)
                odd = sum;
            result_.adaptive.exact.add(first, sum, odd);
        }
        result_.adaptive.add_counts(
            range.first, range.end,
            round_ == 0 ? std::span<const uint8_t>() : std::span<const uint8_t>(mask_));
    }
    result_.count = count;
    result_.odd_count = odds;
    result_.stats += stats;
    ranges_.add(range);
    if (rounds_) relative_error_ = estimate_relative_error(result_);
}

void FrameAccumulator::add(Range range, std::span<const double> sum,
                           std::span<const double> odd_sum, std::span<const double> layer_sums,
                           uint64_t odd_count, const RenderStats& stats,
                           std::span<const int64_t> exact_sum, std::span<const int64_t> exact_odd) {
    const size_t n = value_count();
    const size_t pixels = size_t(width_) * size_t(height_);
    const bool odd_derived = odd_sum.empty() && range.size() == 1 && odd_count <= 1;
    if (sum.size() != n || (odd_sum.size() != n && !odd_derived) ||
        layer_sums.size() != layer_count() * n)
        throw std::invalid_argument("accumulator: buffer size mismatch");
    if (rounds_ ? exact_sum.size() != pixels || exact_odd.size() != (odd_derived ? 0 : pixels)
                : !exact_sum.empty() || !exact_odd.empty())
        throw std::invalid_argument("accumulator: exact sums mismatch");
    const size_t layers_at = (odd_derived ? 1 : 2) * n;
    add_blocks(
        range, odd_derived, odd_count, stats,
        [&](size_t offset, size_t first, size_t m) {
            if (offset == 0) return sum.subspan(first, m);
            if (offset < layers_at) return odd_sum.subspan(first, m);
            return layer_sums.subspan(offset - layers_at + first, m);
        },
        [&](int part, size_t first, size_t m, std::vector<int64_t>&) {
            return (part == 0 ? exact_sum : exact_odd).subspan(first, m);
        });
}

void FrameAccumulator::add(Range range, const ReportValues& values, bool odd_omitted,
                           uint64_t odd_count, const RenderStats& stats) {
    if (odd_omitted && !(range.size() == 1 && odd_count <= 1))
        throw std::invalid_argument("accumulator: odd_sum omitted for a range of several");
    if (!values.complete() || values.count() != report_value_count(odd_omitted))
        throw std::invalid_argument("accumulator: buffer size mismatch");
    const size_t exact_at = report_exact_at(odd_omitted);
    const size_t pixels = size_t(width_) * size_t(height_);
    std::vector<double> scratch_sum, scratch_other, scratch_exact;
    try {
        add_blocks(
            range, odd_omitted, odd_count, stats,
            [&](size_t offset, size_t first, size_t m) {
                return values.block(offset + first, m, offset == 0 ? scratch_sum : scratch_other);
            },
            // The words are int64 (proto/render.proto): copied out of the 8-byte values.
            [&](int part, size_t first, size_t m, std::vector<int64_t>& out) {
                const std::span<const double> words =
                    values.block(exact_at + size_t(part) * pixels + first, m, scratch_exact);
                out.resize(m);
                std::memcpy(out.data(), words.data(), m * sizeof(int64_t));
                return std::span<const int64_t>(out);
            });
    } catch (const std::exception& e) {
        // A spooled report's file could not be read back (a disk error): some of its blocks
        // may already be in the sums, and floating-point sums cannot be un-added exactly, so
        // the sums no longer match their ranges. Going on would merge wrong values (and the
        // worker's retry would add them again). The server stops instead: restarted, it
        // resumes from the frame's checkpoint and leases again what merged since, as after any
        // crash, so nothing is lost or counted twice.
        Log("error", "report_unreadable").kv("error", e.what()).kv("action", "abort");
        std::abort();
    }
}

Image FrameAccumulator::average() const {
    if (result_.count == 0) return Image(width_, height_);
    // render's own mean: an adaptive pixel's sum over its own count (render_iterations.h).
    return mean_image(result_);
}

std::vector<NamedLayer> FrameAccumulator::layer_averages() const {
    return output_layers(result_);
}

void FrameAccumulator::save(const std::filesystem::path& file, double elapsed_seconds) const {
    const char* magic = rounds_ ? kMagicAdaptive : kMagic;
    std::string header;
    header.append(magic, 8);
    put(header, uint32_t(width_));
    put(header, uint32_t(height_));
    put(header, uint64_t(result_.count));
    put(header, uint64_t(result_.odd_count));
    put(header, uint64_t(result_.stats.samples));
    put(header, uint64_t(result_.stats.rays));
    put(header, uint64_t(result_.stats.non_finite));
    put(header, double(elapsed_seconds));
    put(header, uint64_t(result_.stats.vpl_candidates));
    put(header, uint64_t(result_.stats.vpl_accepted));
    put(header, uint32_t(result_.layers.mode()));
    put(header, uint64_t(layer_count()));
    if (rounds_) {
        put(header, uint64_t(rounds_->first(1)));
        put(header, uint64_t(rounds_->end(1)));
        put(header, uint64_t(round_));
    }
    std::vector<Range> ranges = ranges_.ranges();
    put(header, uint64_t(ranges.size()));
    for (const Range& r : ranges) {
        put(header, r.first);
        put(header, r.end);
    }
    std::filesystem::create_directories(file.parent_path());
    std::filesystem::path tmp = file;
    tmp += ".tmp";
    int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
    if (fd < 0)
        throw std::runtime_error("cannot create " + tmp.string() + ": " + std::strerror(errno));
    try {
        write_all(fd, header.data(), header.size(), tmp);
        const auto& s = result_.sum.values();
        const auto& o = result_.odd_sum.values();
        write_all(fd, reinterpret_cast<const char*>(s.data()), s.size() * sizeof(double), tmp);
        write_all(fd, reinterpret_cast<const char*>(o.data()), o.size() * sizeof(double), tmp);
        for (size_t l = 0; l < layer_count(); ++l) {
            const auto& values = result_.layers.buffer(l).values();
            write_all(fd, reinterpret_cast<const char*>(values.data()),
                      values.size() * sizeof(double), tmp);
        }
        if (rounds_) {
            auto write_vector = [&](const auto& v) {
                write_all(fd, reinterpret_cast<const char*>(v.data()), v.size() * sizeof(v[0]),
                          tmp);
            };
            write_vector(result_.adaptive.exact.sums());
            write_vector(result_.adaptive.exact.odd_sums());
            write_vector(result_.adaptive.count);
            write_vector(result_.adaptive.odd_count);
            if (round_ > 0) write_vector(mask_);
        }
        write_all(fd, magic, 8, tmp);
        if (::fsync(fd) != 0)
            throw std::runtime_error("cannot sync " + tmp.string() + ": " + std::strerror(errno));
    } catch (...) {
        ::close(fd);
        std::remove(tmp.c_str());
        throw;
    }
    ::close(fd);
    std::filesystem::rename(tmp, file);
}

FrameAccumulator FrameAccumulator::load(const std::filesystem::path& file,
                                        double* elapsed_seconds) {
    std::ifstream in(file, std::ios::binary);
    if (!in) throw std::runtime_error("cannot open checkpoint " + file.string());
    char magic[8];
    if (!in.read(magic, 8) ||
        (std::memcmp(magic, kMagic, 8) != 0 && std::memcmp(magic, kMagicVersion1, 8) != 0 &&
         std::memcmp(magic, kMagicAdaptive, 8) != 0))
        throw std::runtime_error("checkpoint " + file.string() + " has a bad header");
    const bool version1 = std::memcmp(magic, kMagicVersion1, 8) == 0;
    const bool adaptive = std::memcmp(magic, kMagicAdaptive, 8) == 0;
    const char* trailer = version1 ? kMagicVersion1 : adaptive ? kMagicAdaptive : kMagic;
    uint32_t width = 0, height = 0;
    uint64_t count = 0, odd_count = 0, samples = 0, rays = 0, non_finite = 0, n_ranges = 0;
    double elapsed = 0;
    get(in, width, file);
    get(in, height, file);
    get(in, count, file);
    get(in, odd_count, file);
    get(in, samples, file);
    get(in, rays, file);
    get(in, non_finite, file);
    get(in, elapsed, file);
    uint32_t mode = 0;
    uint64_t layers = 0, vpl_candidates = 0, vpl_accepted = 0;
    if (!version1) {
        get(in, vpl_candidates, file);
        get(in, vpl_accepted, file);
        get(in, mode, file);
        get(in, layers, file);
    }
    uint64_t first_round = 0, end_round = 0, round = 0;
    if (adaptive) {
        get(in, first_round, file);
        get(in, end_round, file);
        get(in, round, file);
    }
    get(in, n_ranges, file);
    if (width == 0 || height == 0 || width > 65536 || height > 65536 || n_ranges > (1u << 26) ||
        mode > uint32_t(LayerMode::Variance) ||
        (adaptive && (first_round < 3 || end_round <= first_round || round > (uint64_t(1) << 40))))
        throw std::runtime_error("checkpoint " + file.string() + " has a bad header");
    RenderSettings settings;
    settings.layers = LayerMode(mode);
    if (adaptive) {
        // The rounds from their first boundaries: round 1 is (min, min + L].
        settings.adaptive = 1;
        settings.adaptive_min_iterations = first_round - 1;
        settings.adaptive_round = end_round - first_round;
    }
    FrameAccumulator acc{int(width), int(height), settings};
    if (layers != acc.layer_count())
        throw std::runtime_error("checkpoint " + file.string() + " has a bad layer count");
    uint64_t total = 0;
    for (uint64_t i = 0; i < n_ranges; ++i) {
        Range r;
        get(in, r.first, file);
        get(in, r.end, file);
        if (r.end <= r.first)
            throw std::runtime_error("checkpoint " + file.string() + " has an empty range");
        acc.ranges_.add(r);
        total += r.size();
    }
    if (total != count || acc.ranges_.total() != count)
        throw std::runtime_error("checkpoint " + file.string() + ": ranges do not match count");
    auto& s = acc.result_.sum.values();
    auto& o = acc.result_.odd_sum.values();
    if (!in.read(reinterpret_cast<char*>(s.data()), std::streamsize(s.size() * sizeof(double))) ||
        !in.read(reinterpret_cast<char*>(o.data()), std::streamsize(o.size() * sizeof(double))))
        throw std::runtime_error("checkpoint " + file.string() + " is truncated");
    for (size_t l = 0; l < acc.layer_count(); ++l) {
        auto& values = acc.result_.layers.buffer(l).values();
        if (!in.read(reinterpret_cast<char*>(values.data()),
                     std::streamsize(values.size() * sizeof(double))))
            throw std::runtime_error("checkpoint " + file.string() + " is truncated");
    }
    if (adaptive) {
        auto read_vector = [&](auto& v) {
            if (!in.read(reinterpret_cast<char*>(v.data()),
                         std::streamsize(v.size() * sizeof(v[0]))))
                throw std::runtime_error("checkpoint " + file.string() + " is truncated");
        };
        const size_t pixels = size_t(width) * size_t(height);
        std::vector<int64_t> sum(pixels), odd(pixels);
        read_vector(sum);
        read_vector(odd);
        acc.result_.adaptive.exact.add(0, sum, odd);
        read_vector(acc.result_.adaptive.count);
        read_vector(acc.result_.adaptive.odd_count);
        std::vector<uint8_t> mask;
        if (round > 0) {
            mask.resize(pixels);
            read_vector(mask);
            for (uint8_t m : mask)
                if (m > 1)
                    throw std::runtime_error("checkpoint " + file.string() + " has a bad mask");
        }
        acc.set_mask(round, std::move(mask));
    }
    if (!in.read(magic, 8) || std::memcmp(magic, trailer, 8) != 0)
        throw std::runtime_error("checkpoint " + file.string() + " is truncated");
    acc.result_.count = count;
    acc.result_.odd_count = odd_count;
    acc.result_.stats.samples = samples;
    acc.result_.stats.rays = rays;
    acc.result_.stats.non_finite = non_finite;
    acc.result_.stats.vpl_candidates = vpl_candidates;
    acc.result_.stats.vpl_accepted = vpl_accepted;
    acc.relative_error_ = count == 0 ? 1.0 : estimate_relative_error(acc.result_);
    if (elapsed_seconds) *elapsed_seconds = elapsed;
    return acc;
}

void write_frame_exr(const std::filesystem::path& file, const Image& image,
                     const std::map<std::string, std::string>& metadata,
                     const std::vector<NamedLayer>& layers) {
    std::filesystem::create_directories(file.parent_path());
    std::filesystem::path tmp = file;
    tmp += ".tmp.exr";
    write_exr(tmp, image, metadata, layers);
    std::filesystem::rename(tmp, file);
}

}  // namespace render::server
