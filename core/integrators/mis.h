#pragma once

namespace render {

// Power heuristic (beta = 2) weight of a technique with density `self` against one with
// density `other`, both in the same measure. Infinite densities (delta techniques) win.
inline float power_heuristic(float self, float other) {
    if (self <= 0) return 0.0f;
    if (!(other > 0)) return 1.0f;
    float ratio = other / self;  // avoids overflow of squares of large densities
    return 1.0f / (1.0f + ratio * ratio);
}

// Power heuristic weight of the first of three techniques' densities (same measure).
inline float power_heuristic3(float self, float other1, float other2) {
    if (!(self > 0)) return 0.0f;
    const float a = other1 / self, b = other2 / self;  // ratios avoid overflowing squares
    return 1.0f / (1.0f + a * a + b * b);
}

// Power heuristic weight of the first of four techniques' densities (same measure).
inline float power_heuristic4(double self, double other1, double other2, double other3) {
    if (!(self > 0)) return 0.0f;
    const double a = other1 / self, b = other2 / self, c = other3 / self;
    return float(1.0 / (1.0 + a * a + b * b + c * c));
}

}  // namespace render
