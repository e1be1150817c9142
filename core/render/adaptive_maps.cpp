#include "core/render/adaptive_maps.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "core/image/srgb.h"
#include "core/image/variance_layers.h"

namespace render {
namespace {

constexpr double kUnknown = std::numeric_limits<double>::quiet_NaN();

// The odd/even estimate of the variance of one value's mean over n iterations, n_o of them odd:
// the halves' means differ with variance s^2 (1/n_o + 1/n_e), the mean has s^2 / n
// (adaptive_mask.h, halves_relative_error). Unknown while a half is empty.
double halves_variance(double sum, double odd, uint64_t count, uint64_t odd_count) {
    if (odd_count == 0 || odd_count >= count) return kUnknown;
    const double n = double(count), n_odd = double(odd_count), n_even = double(count - odd_count);
    const double diff = odd / n_odd - (sum - odd) / n_even;
    return diff * diff * n_odd * n_even / (n * n);
}

// The mean of each pixel's finite values over its 3 x 3 neighbourhood, clipped at the frame's
// edge; unknown where any value in it is unknown.
std::vector<double> window_mean(const std::vector<double>& values, int width, int height) {
    std::vector<double> out(values.size());
    for (int y = 0; y < height; ++y)
        for (int x = 0; x < width; ++x) {
            double sum = 0;
            int n = 0;
            for (int yy = std::max(0, y - 1); yy <= std::min(height - 1, y + 1); ++yy)
                for (int xx = std::max(0, x - 1); xx <= std::min(width - 1, x + 1); ++xx) {
                    sum += values[size_t(yy) * width + xx];
                    ++n;
                }
            out[size_t(y) * width + x] = sum / n;  // NaN spreads: unknown
        }
    return out;
}

// The ramp's stops, sRGB-encoded: dark blue, purple, red, orange, light yellow.
constexpr float kRamp[][3] = {
    {13, 8, 64}, {84, 20, 140}, {190, 45, 95}, {245, 130, 40}, {252, 232, 130}};
constexpr int kStops = sizeof kRamp / sizeof kRamp[0];
constexpr float kGrey = 128;

Rgb linear_of(float r, float g, float b) {
    return {srgb_to_linear(r / 255.0f), srgb_to_linear(g / 255.0f), srgb_to_linear(b / 255.0f)};
}

// Interpolated in sRGB (even steps on screen), returned linear (write_png_preview encodes).
Rgb ramp(double t) {
    t = std::clamp(t, 0.0, 1.0) * (kStops - 1);
    const int i = std::min(int(t), kStops - 2);
    const float f = float(t - i);
    float c[3];
    for (int k = 0; k < 3; ++k) c[k] = kRamp[i][k] + f * (kRamp[i + 1][k] - kRamp[i][k]);
    return linear_of(c[0], c[1], c[2]);
}

}  // namespace

PixelMaps pixel_maps(const IterationResult& result) {
    PixelMaps maps;
    maps.width = result.sum.width();
    maps.height = result.sum.height();
    const size_t pixels = size_t(maps.width) * size_t(maps.height);
    const bool adaptive = !result.adaptive.empty();
    maps.samples.resize(pixels);
    for (size_t p = 0; p < pixels; ++p)
        maps.samples[p] = double(adaptive ? result.adaptive.count[p] : result.count);
    if (result.count == 0) return maps;
    maps.variance.resize(pixels);
    if (result.layers.mode() == LayerMode::Variance) {
        const AccumulationBuffer& squares = result.layers.buffer(0);
        for (size_t p = 0; p < pixels; ++p) {
            double v = 0;
            for (int c = 0; c < 3; ++c)
                v +=
                    variance_of_mean(result.sum.channel(p, c), squares.channel(p, c), result.count);
            maps.variance[p] = v / 3;
        }
        maps.variance_source = "variance layer";
        return maps;
    }
    for (size_t p = 0; p < pixels; ++p) {
        const uint64_t count = adaptive ? result.adaptive.count[p] : result.count;
        const uint64_t odd = adaptive ? result.adaptive.odd_count[p] : result.odd_count;
        double v = 0;
        for (int c = 0; c < 3; ++c)
            v +=
                halves_variance(result.sum.channel(p, c), result.odd_sum.channel(p, c), count, odd);
        maps.variance[p] = v / 3;
    }
    maps.variance = window_mean(maps.variance, maps.width, maps.height);
    maps.variance_source = "odd/even halves";
    return maps;
}

PixelMaps pixel_maps_from_exr(const Image& image, const Image* variance_layer,
                              const Image* samples_layer,
                              const std::map<std::string, std::string>& metadata) {
    PixelMaps maps;
    maps.width = image.width();
    maps.height = image.height();
    const size_t pixels = image.pixel_count();
    for (const Image* layer : {variance_layer, samples_layer})
        if (layer && layer->pixel_count() != pixels)
            throw std::invalid_argument("a layer of another size than the image");
    maps.samples.assign(pixels, kUnknown);
    if (samples_layer) {
        for (size_t p = 0; p < pixels; ++p) maps.samples[p] = samples_layer->at(p).r;
    } else if (auto it = metadata.find("render:iterations"); it != metadata.end()) {
        try {
            maps.samples.assign(pixels, double(std::stoull(it->second)));
        } catch (const std::exception&) {
        }
    }
    if (variance_layer) {
        maps.variance.resize(pixels);
        for (size_t p = 0; p < pixels; ++p) {
            const Rgb v = variance_layer->at(p);
            maps.variance[p] = (double(v.r) + v.g + v.b) / 3;
        }
        maps.variance_source = "variance layer";
    }
    return maps;
}

HeatMap heat_map(std::span<const double> values, int width, int height, bool log_scale) {
    if (values.size() != size_t(width) * size_t(height))
        throw std::invalid_argument("heat_map: values of another size");
    HeatMap map;
    map.log_scale = log_scale;
    map.image = Image(width, height);
    std::vector<double> finite;
    finite.reserve(values.size());
    for (double v : values)
        if (std::isfinite(v) && (!log_scale || v > 0))
            finite.push_back(log_scale ? std::log10(v) : v);
    double lo = 0, hi = 0;
    if (!finite.empty()) {
        std::sort(finite.begin(), finite.end());
        const size_t last = finite.size() - 1;
        const size_t a = log_scale ? size_t(std::floor(0.01 * double(last))) : 0;
        const size_t b = log_scale ? size_t(std::ceil(0.99 * double(last))) : last;
        lo = finite[a];
        hi = finite[b];
    }
    map.low = log_scale ? std::pow(10.0, lo) : lo;
    map.high = log_scale ? std::pow(10.0, hi) : hi;
    const Rgb grey = linear_of(kGrey, kGrey, kGrey);
    for (size_t p = 0; p < values.size(); ++p) {
        const double v = values[p];
        if (!std::isfinite(v)) {
            map.image.set(p, grey);
            continue;
        }
        double x = v;
        if (log_scale) x = v > 0 ? std::log10(v) : -std::numeric_limits<double>::infinity();
        const double t = !std::isfinite(x) ? 0.0 : hi > lo ? (x - lo) / (hi - lo) : 0.5;
        map.image.set(p, ramp(t));
    }
    return map;
}

}  // namespace render
