#pragma once

#include <cstdint>
#include <string>

#include "core/base/render_stats.h"
#include "core/image/technique_layers.h"
#include "core/integrators/importance_weights.h"
#include "core/integrators/roulette.h"
#include "core/integrators/volpt_technique.h"

namespace render {

// Everything that, together with the scene, determines a rendered image.
struct RenderSettings {
    std::string algorithm = "pt";
    int max_depth = -1;  // Mitsuba's meaning: segments per path, -1 = unbounded
    int rr_depth = 5;    // Russian roulette from this path depth on
    // How roulette ends paths (pt and the bidirectional family; core/integrators/roulette.h).
    RoulettePolicy roulette = RoulettePolicy::Throughput;
    uint64_t seed = 0;  // job seed: part of every random stream key
    int threads = 0;    // 0 = all cores; never changes the image

    // Bidirectional family (lt, bpt, ppm, bpm, vcm).
    // Initial merging radius: a fraction of the scene's bounding-sphere radius when
    // radius_factor > 0 (SmallVCM's rule; it used 0.003), else (the default) radius_pixels
    // pixel footprints (merge_radius.h); and the radius reduction exponent. The defaults were
    // chosen by equal-time error (docs/reference/algorithms.md, "Merging radius").
    double radius_factor = 0;
    double radius_pixels = 1;
    double alpha = 0.75;
    // Light paths per iteration; 0 = one per pixel (SmallVCM's choice: every eye path then has
    // a light path of its own to connect to).
    uint64_t light_path_count = 0;
    // MIS heuristic exponent: 2 = power heuristic (default), 1 = balance heuristic.
    int mis_power = 2;
    // volpt: equi-angular sampling of single scattering toward finite lights, combined by MIS
    // with distance sampling (off: distance sampling only, for comparisons).
    bool equiangular = true;
    // volpt: joint path sampling (Georgiev et al. 2013) of double scattering on the camera ray in
    // homogeneous media, combined by MIS with the other techniques (docs/design/media.md).
    bool jis = true;
    // volpt: which techniques sample double scattering (a diagnostic; All = the MIS above).
    VolptTechnique volpt_technique = VolptTechnique::All;
    // bpt, vcm: joint (J1, vertex-segment) connections from eye segments in homogeneous media,
    // one more technique in the MIS (docs/design/media.md, "Joint connections in bpt and vcm").
    bool joint_connections = false;
    // bpt: J2 (segment-segment) connections on the light's emission ray beside J1
    // (--joint-connections all).
    bool joint2_connections = false;
    // upbp: whether connections are made, which merges join them (surfaces, photon points P-P3D,
    // query beams P-B2D) and the volume estimators' radius schedule (0: the surfaces' radius_factor
    // and alpha; docs/design/media.md, "Points, beams and paths").
    bool vertex_connections = true;
    bool surface_merging = true;
    bool photon_points = true;
    bool query_beams = true;
    double volume_radius_factor = 0;
    double volume_alpha = 1;
    // upbp: photon beams (B-B1D), short (each ends at its light subpath's sampled distance) or
    // long (to the next surface), and their MIS constant eta_1 in units of the beam radius
    // (0.5: SmallUPBP's r / 2; 2: the kernel's support 2 r).
    bool photon_beams = true;
    bool short_photon_beams = true;
    double photon_beam_eta = 0.5;
    // upbp: the fraction of each iteration's light paths (the first ones) whose segments in media
    // become photon beams (1: all). 0.01: the fraction `scripts/bench --only upbp-defaults`
    // chose by equal-time RMSE (docs/data/upbp/defaults.json, docs/design/media.md).
    double photon_beam_paths = 0.01;
    // upbp: the same fraction for the photon points that query beams gather (1: all; 0.01 as
    // above).
    double query_beam_paths = 0.01;
    // vpl: light paths per iteration whose non-delta vertices are the virtual point lights, and
    // the optional distance clamp of their geometry term (a fraction of the scene's
    // bounding-sphere radius; 0 = unclamped) with its schedule (shrinking: consistent).
    uint64_t vpl_paths = 64;
    double vpl_clamp = 0;
    bool vpl_clamp_shrinking = true;
    // vpl: the importance-driven VPL distribution (Georgiev and Slusallek 2010): camera points
    // per iteration that estimate each VPL's contribution, and the lowest acceptance probability.
    bool vpl_importance = false;
    int importance_records = 100;
    double vpl_min_probability = 0.05;
    // ic: importance caching (Georgiev, Krivanek, Popov, Slusallek 2012) over the VPLs: records
    // per pixel on a jittered screen grid, VPL samples per technique (F, U, B, C) and shading
    // point, and the heuristic that weights the techniques.
    double ic_record_density = 1.0 / 16.0;
    int ic_samples = 4;
    IcHeuristic ic_heuristic = IcHeuristic::AlphaMax;
    // ic: false, the importance caches; true, every shading point draws its VPLs in proportion
    // to their power (the baseline of the paper's comparisons).
    bool ic_power_only = false;
    // ic: the distribution optimisation of alpha-max (importance_optimise.h).
    bool ic_optimise = false;
    // bpt: connections to the vertices of the pixel's own light path (false), or to light
    // vertices drawn from importance caches over the first ic_light_paths light paths (true),
    // connection_samples per technique and eye vertex.
    bool ic_connections = false;
    uint64_t ic_light_paths = 64;
    int connection_samples = 1;
    // Per-technique images (extra EXR layers): none, connection/merging, or per (s, t).
    LayerMode layers = LayerMode::None;
    // Adaptive sampling (docs/reference/adaptive-sampling.md), pixel algorithms only: 0 = off,
    // else the per-pixel relative error under which a pixel stops taking iterations. Every pixel
    // takes the first adaptive_min_iterations; after that the active pixels are chosen again
    // every adaptive_round iterations, from the sums at that fixed boundary.
    double adaptive = 0;
    uint64_t adaptive_min_iterations = 16;
    uint64_t adaptive_round = 8;
};

}  // namespace render
