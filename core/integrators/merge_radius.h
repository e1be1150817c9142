#pragma once

// The merging radius schedule of progressive photon mapping and VCM. It is a function of the
// global iteration index alone (DESIGN.md, iteration contract), so every worker rendering any
// range of iterations uses the same radii, and the merged image is exact.

#include <cstdint>

namespace render {

class PerspectiveCamera;
struct SceneSphere;

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

// The side of one pixel's footprint at the scene: the pixel's side on the image plane at
// distance 1 (sqrt(image plane area / pixels)) times the distance from the camera to the
// bounding sphere's centre, or the sphere's radius when the camera is inside it (its first hits
// then lie about that far away). Independent of the scene's scale and of the resolution's
// aspect (docs/reference/algorithms.md, "Merging radius").
double pixel_footprint(const PerspectiveCamera& camera, const SceneSphere& sphere);

// r_1 in world units: radius_factor x the bounding sphere's radius when radius_factor > 0
// (the scene-relative rule), else radius_pixels x pixel_footprint (the default: the kernel
// covers the same share of a pixel, and with one light path per pixel holds the same number of
// photons, at every resolution and scene scale).
double initial_merge_radius(double radius_factor, double radius_pixels,
                            const PerspectiveCamera& camera, const SceneSphere& sphere);

}  // namespace render
