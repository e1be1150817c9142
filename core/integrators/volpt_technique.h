#pragma once

namespace render {

// Which of volpt's techniques produce the double-scattering paths camera -> c -> b -> light
// (`--volpt-technique`, a diagnostic for the convergence-rate experiment of joint path sampling,
// docs/design/media.md "Joint path sampling"). Every choice is an unbiased estimator of the same
// image.
enum class VolptTechnique {
    // The default: distance sampling with light sampling (DL) and phase sampling (DP),
    // equi-angular sampling (EL, with --equiangular on) and joint sampling (J3, with --jis on),
    // combined by the power heuristic.
    All,
    // Distance sampling and light sampling alone, every weight 1 (next-event estimation only:
    // emission that phase or BSDF sampling finds from a non-delta vertex counts 0). For double
    // scattering this is the "0-connection": c and b by distance sampling, then a shadow ray.
    // Turns equi-angular and joint sampling off.
    DistanceLight,
    // J3 alone, weight 1, for every path it can produce (the other techniques give those paths
    // weight 0); every other path as with All. Turns joint sampling on.
    Joint,
};

}  // namespace render
