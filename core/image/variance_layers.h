#pragma once

// Per-pixel error layers (docs/reference/variance-layers.md): from a frame's merged sums, the
// variance of each pixel's estimate and the two half images (odd and even iterations). The
// sums are the iteration contract's (docs/design/design.md): the sum of the iterations' pixel
// values, its odd-iteration part, and the sum of the values' squares; all three merge by
// addition, so the layers are the same for any split of the iterations.

#include <cstdint>
#include <vector>

#include "core/image/image.h"

namespace render {

// The estimated variance of the mean of `count` independent values with sum `sum` and sum of
// squares `sum_squares`: the unbiased sample variance (Q - S^2/N) / (N - 1), divided by N.
// 0 for fewer than two values, and 0 when Q - S^2/N is within the rounding error of the sums
// (at most 4 N eps Q for any summation order: a constant value's variance is exactly 0, never
// the residue of rounding). A sum of squares too large for a double gives +infinity (the
// caller clamps it to what its image format holds).
double variance_of_mean(double sum, double sum_squares, uint64_t count);

// A double as an image value: NaN becomes 0 and anything beyond the float range the largest
// float of its sign, so that no NaN or infinity reaches a written layer.
float finite_image_value(double value);

// The layers "variance" (variance_of_mean per pixel and channel), "odd_half" (mean of the odd
// iterations) and "even_half" (mean of the even ones; a half with no iterations is black), in
// that order. `sum`, `odd_sum` and `sum_squares` are buffers of one frame; `count` iterations
// of which `odd_count` odd.
std::vector<NamedLayer> variance_layers(const AccumulationBuffer& sum,
                                        const AccumulationBuffer& odd_sum,
                                        const AccumulationBuffer& sum_squares, uint64_t count,
                                        uint64_t odd_count);

}  // namespace render
