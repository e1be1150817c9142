#pragma once

// The merging radius schedule of progressive photon mapping and VCM. It is a function of the
// global iteration index alone (DESIGN.md, iteration contract), so every worker rendering any
// range of iterations uses the same radii, and the merged image is exact.

#include <cstdint>

namespace render {

// r_i = r1 * i^((alpha - 1) / 2) for the 1-based iteration i (the radius reduction of
// Knaus and Zwicker 2011, as the VCM paper uses it). alpha in (0, 1]: 1 keeps the radius fixed.
// The result never falls below min_merge_radius(), so 1 / (pi r^2 N) stays finite in float.
double merge_radius(double r1, double alpha, uint64_t iteration);

// The same for a kernel of the given dimension (UPBP's volume estimators): r_i = r1 *
// i^((alpha - 1) / dimension), so that the kernel's support shrinks as i^(alpha - 1) whatever
// its dimension (3: photon points in a ball, 2: a disc around a query beam).
double merge_radius_in(double r1, double alpha, uint64_t iteration, int dimension);

// Floor of the schedule, 1e-18: pi r^2 stays above float's smallest normal number (1e-38), so
// the merging normalisation 1 / (pi r^2 N) is finite for any light-path count N >= 1.
double min_merge_radius();

}  // namespace render
