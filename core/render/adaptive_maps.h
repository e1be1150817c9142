#pragma once

// The per-pixel maps the service's dashboard shows beside the preview
// (docs/reference/adaptive-sampling.md, "Seeing it"): each pixel's variance and its sample count,
// and their false-colour images.

#include <cstdint>
#include <map>
#include <span>
#include <string>
#include <vector>

#include "core/image/image.h"
#include "core/render/render_iterations.h"

namespace render {

struct PixelMaps {
    int width = 0, height = 0;
    // The variance of each pixel's estimate (its mean over its iterations), the mean over R, G
    // and B; NaN where it is unknown. Empty when no variance can be had.
    std::vector<double> variance;
    // What `variance` is: "variance layer" (the sample variance from the sum of squares,
    // variance_of_mean) or "odd/even halves" (the halves' estimate, over the 3 x 3
    // neighbourhood), "" when empty.
    std::string variance_source;
    // Each pixel's iterations (camera samples): its own count in an adaptive job, else the
    // frame's count for every pixel.
    std::vector<double> samples;
};

// The maps of a frame's merged sums. With the variance layers (LayerMode::Variance) the
// variance is variance_of_mean per channel; otherwise, per channel, the odd/even estimate of the
// mean's variance (m_odd - m_even)^2 n_odd n_even / n^2 (each pixel with its own counts in an
// adaptive job), averaged over the pixel's 3 x 3 neighbourhood (one pixel's estimate has one
// degree of freedom, the window's nine), unknown while a half is empty.
PixelMaps pixel_maps(const IterationResult& result);

// The maps of a finished frame from its EXR: the "variance" layer (the variance layers') and the
// "samples" layer (adaptive), else the `render:iterations` count for every pixel; no variance
// without its layer.
PixelMaps pixel_maps_from_exr(const Image& image, const Image* variance_layer,
                              const Image* samples_layer,
                              const std::map<std::string, std::string>& metadata);

// A false-colour image of one value per pixel, in linear RGB for write_png_preview: a dark-blue
// to yellow ramp over [low, high], linear or over log10 (values <= 0 at the low end); unknown
// (non-finite) values grey. On the log scale low and high are the 1st and 99th percentiles of
// the positive finite values, so that a few fireflies do not flatten the rest; on the linear
// scale (counts) the least and largest finite value. One value everywhere: the ramp's middle.
// The caller shows low and high as the legend.
struct HeatMap {
    Image image;
    double low = 0, high = 0;
    bool log_scale = false;
};
HeatMap heat_map(std::span<const double> values, int width, int height, bool log_scale);

}  // namespace render
