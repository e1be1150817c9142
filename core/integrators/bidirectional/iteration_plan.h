#pragma once

// What one iteration of the bidirectional family or of many-light rendering does, decided once
// from the configuration, the scene and the iteration index: which techniques run, the path
// lengths and counts, this iteration's merging radii and the MIS constants that follow from them.
// The passes read the plan, never the configuration.

#include <cstdint>

#include "core/integrators/bidirectional/config.h"
#include "core/integrators/bidirectional/vcm_mis.h"

namespace render {

class Scene;

namespace bidirectional {

struct IterationPlan {
    // The techniques. light_tracing_only: lt, the light subpaths' camera connections alone.
    // ppm: one unweighted merge at the first non-delta eye vertex.
    bool light_tracing_only = false;
    bool ppm = false;
    bool vertex_connections = false;  // every connection technique (s, t)
    bool merging = false;             // light vertices stored for merging (ppm, bpm, vcm, upbp)
    // Which merges run (ppm, bpm, vcm: surfaces and photon points; upbp: as configured).
    bool merge_surfaces = false, merge_points = false, query_beams = false, photon_beams = false;
    bool short_photon_beams = true;
    bool joint = false;           // J1 connections (bpt, vcm in a scene with homogeneous media)
    bool joint2 = false;          // and J2 on the light path's rays (bpt only)
    bool ic_connections = false;  // bpt whose connections draw light vertices from caches
    // Many-light estimators over the iteration's VPLs (weight 1, none of the VCM MIS).
    bool vpl = false, ic = false;
    // Light-subpath techniques count only where they read the medium rule as camera paths do
    // (docs/design/media.md, "Which medium a path is in"): light subpaths stop at a boundary
    // they reach against its declaration, connections and merges check the medium where the two
    // subpaths meet, and eye subpaths drop the techniques whose light subpath would cross such
    // a boundary. Not yet beside upbp's beams, joint connections and the many-light estimators,
    // whose terms do not know it.
    bool camera_medium_rule = false;

    int max_length = 0;  // path segments (max_depth; unbounded: INT_MAX / 4)
    int rr_depth = 5;
    RoulettePolicy roulette = RoulettePolicy::Throughput;
    uint64_t pixel_count = 0, light_path_count = 0;
    // upbp: the light paths 0 .. photon_beam_path_count - 1 make photon beams (all where there
    // are no photon beams).
    uint64_t photon_beam_path_count = 0;
    // upbp: query beams gather the photon points of light paths 0 .. query_beam_path_count - 1.
    uint64_t query_beam_path_count = 0;

    // Merging radii: surfaces, photon points (P-P3D), query beams (P-B2D), photon beams (B-B1D).
    double radius = 0, volume_radius = 0, beam_radius = 0, photon_beam_radius = 0;
    // 1 / eta, with the report's eta_VCM = pi r^2 N_light (the ratio of merging to connection
    // densities of the same path) and its analogues for the other kernels: each merge's kernel
    // and the 1 / N_light of the light paths.
    float vm_normalization = 0, vm_normalization_volume = 0, beam_normalization = 0;
    float photon_beam_normalization = 0;
    int mis_power = 2;
    MisTechniques mis_techniques;

    // Many lights: the squared distance clamp of VPL connections (0: none) and 1 / N_L (each
    // light path is one sample of the VPL estimator).
    float vpl_clamp2 = 0, vpl_scale = 0;
    VplImportance vpl_importance;
    // Importance caching: the light paths whose vertices the caches cover (ic: all; bpt: a
    // prefix) and 1 / their number (the caches average over those paths).
    uint64_t ic_light_path_count = 0;
    float ic_connection_scale = 0;
    ImportanceCacheSettings cache;

    bool many_lights() const { return vpl || ic; }
    bool uses_importance_caches() const { return ic || ic_connections; }
};

// `iteration` is the 1-based global iteration index (IterationKey::iteration).
IterationPlan plan_iteration(const BidirectionalConfig& config, const Scene& scene,
                             uint64_t iteration);
IterationPlan plan_iteration(const ManyLightConfig& config, const Scene& scene, uint64_t iteration);

}  // namespace bidirectional
}  // namespace render
