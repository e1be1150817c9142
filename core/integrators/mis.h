#pragma once

namespace render {

// Power heuristic (beta = 2) weight of a technique with density `pdf_a` against one with
// density `pdf_b`, both in the same measure. Infinite densities (delta techniques) win.
inline float power_heuristic(float pdf_a, float pdf_b) {
    if (pdf_a <= 0) return 0.0f;
    if (!(pdf_b > 0)) return 1.0f;
    float ratio = pdf_b / pdf_a;  // avoids overflow of squares of large densities
    return 1.0f / (1.0f + ratio * ratio);
}

}  // namespace render
