#pragma once

// The settings of the bidirectional family (lt, bpt, ppm, bpm, vcm, upbp) and of the many-light
// estimators that reuse its light pass (vpl, ic), one struct per technique they configure. The
// algorithm table (core/render/algorithms.cpp) fills them from the render options; the iteration
// reads them only through its plan (iteration_plan.h).

#include <cstdint>

#include "core/integrators/importance_weights.h"
#include "core/integrators/roulette.h"

namespace render {

enum class BidirectionalAlgorithm {
    LightTracing,  // light paths connected to the camera (t = 1)
    Bpt,           // every connection technique (s, t): the VCM report with merging disabled
    Ppm,           // merging at the first non-delta eye vertex, no MIS (Hachisuka 2008)
    Bpm,           // merging at every eye vertex, MIS between merges
    Vcm,           // connections and merges, full MIS (Georgiev et al. 2012)
    Upbp,          // vcm with query beams and photon beams in media (Krivanek et al. 2014)
};

// The subpaths: their length and how many light subpaths an iteration traces.
struct SubpathSettings {
    int max_depth = -1;  // Mitsuba's meaning: path segments, -1 = unbounded
    int rr_depth = 5;
    uint64_t light_path_count = 0;                         // 0 = one per pixel
    RoulettePolicy roulette = RoulettePolicy::Throughput;  // core/integrators/roulette.h
};

// The merging radius of iteration i: r_i = r_1 i^((alpha - 1) / 2), r_1 = radius_factor x the
// scene's bounding-sphere radius when radius_factor > 0, else radius_pixels x the camera's pixel
// footprint at the scene (merge_radius.h; the defaults: docs/reference/algorithms.md).
struct MergeSchedule {
    double radius_factor = 0;
    double radius_pixels = 1;
    double alpha = 0.75;
};

// upbp's combination (docs/design/media.md): which merges join the connections (surfaces, photon
// points P-P3D, query beams P-B2D: photon points gathered along whole camera segments in media,
// photon beams B-B1D: the light subpaths' segments in media gathered by camera segments with a
// 1-D kernel), and the volume estimators' own radius schedule (a fraction of the scene's
// bounding-sphere radius; 0: the surfaces').
struct UpbpSettings {
    bool vertex_connections = true;  // off: merges only (bpm with query beams)
    bool surface_merging = true;
    bool photon_points = true;
    bool query_beams = false;
    bool photon_beams = false;
    // Each beam ends at its subpath's sampled distance (UPBP's default) instead of at the next
    // surface.
    bool short_photon_beams = true;
    // The MIS constant eta_1 in units of r_1 (0.5: SmallUPBP's r / 2; 2: the kernel's support).
    double photon_beam_eta = 0.5;
    // The fraction of the iteration's light paths, the first ones, whose segments become photon
    // beams (SmallUPBP's photon beam path count): B-B1D's normalisation and MIS constant count
    // those K paths instead of all N (iteration_plan.cpp). 0.01: the fraction the measured sweep
    // `scripts/bench --only upbp-defaults` chose (docs/data/upbp/defaults.json).
    double photon_beam_paths = 0.01;
    // The same for the photon points that query beams gather (SmallUPBP's per-estimator light
    // path counts): P-B2D's normalisation and MIS constant count those paths. Fewer photons make
    // each query cheaper and give P-B2D less of the paths other techniques sample better (a
    // merge's density counts every light path as an independent sample, though all of them share
    // the one eye subpath: docs/design/media.md). 0.01 as above.
    double query_beam_paths = 0.01;
    double volume_radius_factor = 0;
    double volume_alpha = 1;
};

// Joint connections in homogeneous media (bpt, vcm; docs/design/media.md). J1: each eye segment in
// a medium also joins every vertex of the pixel's light path through a medium vertex sampled by
// half-line equi-angular sampling toward it (the "vertex-segment" connection, Georgiev et al.
// 2013). J2 (bpt only, with J1): the segment-segment connection on the light's rays as well.
struct JointConnectionSettings {
    bool j1 = false;
    bool j2 = false;
};

// Importance caching's records and draws (ic, and bpt's ic connections): records per pixel
// (jittered screen grid), light vertices drawn per distribution and shading point, and the
// heuristic between the four distributions (importance_weights.h).
struct ImportanceCacheSettings {
    double record_density = 1.0 / 16.0;
    int samples = 4;
    IcHeuristic heuristic = IcHeuristic::AlphaMax;
    // ic only: no records; every shading point draws its 4 x samples VPLs in proportion to their
    // power (the baseline importance caching is compared with).
    bool power_only = false;
    // ic with alpha-max: each record's tables optimised for its own alpha-max winners.
    bool optimise = false;
};

// bpt's importance-cached connections: each eye vertex connects to light vertices drawn from the
// importance caches over the vertices of the iteration's first `light_paths` light paths,
// instead of to the vertices of one light path.
struct IcConnectionSettings {
    bool enabled = false;
    uint64_t light_paths = 64;
};

struct BidirectionalConfig {
    BidirectionalAlgorithm algorithm = BidirectionalAlgorithm::Vcm;
    SubpathSettings subpaths;
    int mis_power = 2;  // 2 = power heuristic, 1 = balance heuristic
    MergeSchedule merging;
    UpbpSettings upbp;                    // upbp only
    JointConnectionSettings joint;        // bpt, vcm
    IcConnectionSettings ic_connections;  // bpt only
    ImportanceCacheSettings cache;        // with ic_connections
};

// Many-light rendering over the iteration's light paths (vpl, ic).
enum class ManyLightEstimator {
    // Instant radiosity: the non-delta vertices of the light paths are virtual point lights; the
    // eye follows delta lobes and, at its first non-delta vertex, adds next-event estimation and
    // a connection to every VPL, all with weight 1.
    Vpl,
    // Importance caching over the same VPLs: at the first non-delta eye vertex, next-event
    // estimation and a few VPLs drawn from the four distributions of the nearest records,
    // weighted by MIS between the distributions (importance_weights.h).
    Ic,
};

// How the VPL connection's distance clamp changes over iterations.
enum class VplClampSchedule {
    Fixed,      // d_min in every iteration: biased, bounded variance
    Shrinking,  // d_min * i^(-1/4): consistent (docs/reference/algorithms.md, many-light rendering)
};

// The connection's geometry term uses max(distance, d_min), d_min = factor x the scene's
// bounding-sphere radius (0: unclamped, unbiased).
struct VplClamp {
    double factor = 0;
    VplClampSchedule schedule = VplClampSchedule::Shrinking;
};

// vpl's importance-driven distribution (Georgiev and Slusallek 2010): each candidate VPL k is
// kept with P_k = max(min(M phi_k / phi, 1), min_probability) and its power divided by P_k;
// phi_k is its contribution to `records` camera points of the same iteration, phi the sum over
// the M candidates.
struct VplImportance {
    bool enabled = false;
    int records = 100;
    double min_probability = 0.05;
};

struct ManyLightConfig {
    ManyLightEstimator estimator = ManyLightEstimator::Vpl;
    SubpathSettings subpaths;  // light_path_count: the VPL paths per iteration
    VplClamp clamp;
    VplImportance importance;       // vpl
    ImportanceCacheSettings cache;  // ic
};

}  // namespace render
