#pragma once

// Russian roulette: when a path that just scattered continues, and with what weight. Two
// policies (render option --roulette; docs/reference/algorithms.md, "Parameters"):
//
//   Throughput  from path depth rr_depth on, survive with q = min(0.95, max(throughput) /
//               max(initial throughput)) (Mitsuba's rule with rr_depth 5; the default).
//   Albedo      at every scattering, survive with q = min(1, max(weight)), weight = f |cos| / pdf
//               of the direction just sampled: the fraction of the path's energy this bounce
//               keeps, so a white wall never ends a path and a dark one ends most (SmallVCM's
//               rule, which plays it by the material's albedo at every bounce). rr_depth is
//               not used.
//
// Either way a survivor's throughput is divided by q, so the estimate is unbiased; the MIS
// densities do not include q (the techniques' weights stay a partition of unity).

#include "core/math/vec.h"
#include "core/sampling/rng.h"

namespace render {

enum class RoulettePolicy { Throughput, Albedo };

// The Albedo policy after a scattering of weight `weight` (f |cos| / pdf of the sampled
// direction): false when the path ends; a survivor's throughput is divided by its survival
// probability. Draws one number from rng only when q < 1. (The Throughput policy stays in each
// integrator, whose exact float operations the images depend on.)
inline bool survives_albedo_roulette(const Rgb& weight, Rgb& throughput, Rng& rng) {
    const float q = weight.max();
    if (!(q > 0)) return false;  // zero or NaN
    if (q >= 1.0f) return true;
    if (rng.next_1d() >= q) return false;
    throughput *= 1.0f / q;
    return true;
}

}  // namespace render
