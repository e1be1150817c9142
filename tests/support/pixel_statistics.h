#pragma once

// Mean of an image whose pixels all estimate the same value independently (furnaces, uniform
// media), with the standard error of that mean from the pixels' spread (tests/support/
// statistics.h).

#include "core/render/render_iterations.h"
#include "tests/support/statistics.h"

namespace render::testing {

using PixelStatistics = MeanEstimate;

inline PixelStatistics pixel_statistics(const IterationResult& r, int channel) {
    MeanAccumulator pixels;
    for (size_t i = 0; i < r.sum.pixel_count(); ++i)
        pixels.add(r.sum.channel(i, channel) / double(r.count));
    return pixels.estimate();
}

}  // namespace render::testing
