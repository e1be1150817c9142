#pragma once

// The bidirectional family on one set of MIS quantities: light tracing, bidirectional path
// tracing, progressive photon mapping, bidirectional photon mapping and vertex connection and
// merging (Georgiev, Krivanek, Davidovic and Slusallek 2012). The implementation follows the
// technical report "Implementing Vertex Connection and Merging" (Georgiev 2012, below "the
// report"): every subpath carries the recursive partial weights dVCM, dVC and dVM, from which
// every technique's MIS weight is computed locally. The algorithms differ only in which
// techniques they enable, which is what BidirectionalMode selects.

#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <vector>

#include "core/integrators/beams_along_ray.h"
#include "core/integrators/importance_weights.h"
#include "core/integrators/integrator.h"
#include "core/materials/surface_bsdf.h"

namespace render {

enum class BidirectionalMode {
    LightTracing,  // light paths connected to the camera (t = 1)
    Bpt,           // every connection technique (s, t), the report with merging disabled
    Ppm,           // merging at the first non-specular eye vertex, no MIS (Hachisuka 2008)
    Bpm,           // merging at every eye vertex, MIS between merges
    Vcm,           // connections and merges, full MIS
    // Many-light rendering (instant radiosity): the non-delta vertices of the iteration's light
    // paths are virtual point lights; the eye follows delta lobes and, at its first non-delta
    // vertex, adds next-event estimation and a connection to every VPL, all with weight 1.
    Vpl,
    // Importance caching over the same VPLs: at the first non-delta eye vertex, next-event
    // estimation and a few VPLs drawn from the four distributions of the nearest importance
    // records, weighted by MIS between the distributions (importance_weights.h).
    Ic,
};

// How the VPL connection's distance clamp changes over iterations (BidirectionalConfig).
enum class VplClampSchedule {
    Fixed,      // d_min in every iteration: biased, bounded variance
    Shrinking,  // d_min * i^(-1/4): consistent (docs/algorithms.md, many-light rendering)
};

struct BidirectionalConfig {
    BidirectionalMode mode = BidirectionalMode::Vcm;
    int max_depth = -1;  // Mitsuba's meaning: path segments, -1 = unbounded
    int rr_depth = 5;
    double radius_factor = 0.003;
    double alpha = 0.75;
    uint64_t light_path_count = 0;  // 0 = one per pixel
    int mis_power = 2;              // 2 = power heuristic, 1 = balance heuristic
    // Vpl: the connection's geometry term uses max(distance, d_min) with d_min = vpl_clamp x
    // the scene's bounding-sphere radius (0: unclamped, unbiased).
    double vpl_clamp = 0;
    VplClampSchedule vpl_clamp_schedule = VplClampSchedule::Shrinking;
    // Vpl: the importance-driven VPL distribution (Georgiev and Slusallek 2010). Each candidate
    // VPL k is kept with P_k = max(min(M phi_k / phi, 1), vpl_min_probability) and its power
    // divided by P_k; phi_k is its contribution to `importance_records` camera points of the
    // same iteration, phi the sum over the M candidates.
    bool vpl_importance = false;
    int importance_records = 100;
    double vpl_min_probability = 0.05;
    // Ic: records per pixel (jittered screen grid), VPLs drawn per technique and shading point,
    // and the heuristic between the techniques.
    double ic_record_density = 1.0 / 16.0;
    int ic_samples = 4;
    IcHeuristic ic_heuristic = IcHeuristic::AlphaMax;
    // Ic: no records; every shading point draws its 4 ic_samples VPLs in proportion to their
    // power (the baseline importance caching is compared with).
    bool ic_power_only = false;
    // Ic with alpha-max: each record's tables optimised for its own alpha-max winners.
    bool ic_optimise = false;
    // Bpt: importance-cached connections. Each eye vertex connects to light vertices drawn
    // from the importance caches (the four distributions of Ic, over the vertices of the
    // iteration's first ic_light_paths light paths) instead of to the vertices of one light
    // path; ic_samples per technique, the records and the heuristic as Ic's.
    bool ic_connections = false;
    uint64_t ic_light_paths = 64;
    // Bpt (with path connections) in homogeneous media: joint (J1) connections. Each eye
    // segment in a medium also joins every vertex of the pixel's light path through a medium
    // vertex sampled by half-line equi-angular sampling toward it, an extra technique in the
    // MIS (Georgiev et al. 2013, the "vertex-segment" connection; docs/media.md).
    bool joint_connections = false;
    // Bpt with joint_connections: J2 as well, the segment-segment connection on the light's
    // emission ray (the first light vertex resampled on it by B2, the eye vertex by J1;
    // docs/media.md, "J2: segment-segment connections").
    bool joint2_connections = false;
    // Vcm as UPBP's combination (algorithm upbp; Krivanek et al. 2014, docs/media.md): which
    // merges join the connections (surfaces, photon points P-P3D, query beams P-B2D: photon
    // points gathered along whole camera segments in media), and the volume estimators' own
    // radius schedule (a fraction of the scene's bounding-sphere radius; 0: the surfaces').
    bool vertex_connections = true;  // off: merges only (bpm with query beams)
    bool surface_merging = true;
    bool photon_points = true;
    bool query_beams = false;
    double volume_radius_factor = 0;
    double volume_alpha = 1;
    // upbp's photon beams (B-B1D, docs/media.md "Photon beams"): the light subpaths' segments in
    // homogeneous media gathered by camera segments with a 1-D kernel of radius r_1 (the volume
    // schedule at dimension 1). short_photon_beams: each beam ends at its subpath's sampled
    // distance (UPBP's default) instead of at the next surface. photon_beam_eta: the MIS constant
    // eta_1 in units of r_1 (0.5: SmallUPBP's r / 2; 2: the kernel's support 2 r).
    bool photon_beams = false;
    bool short_photon_beams = true;
    double photon_beam_eta = 0.5;
};

// One candidate VPL of an iteration of `vpl` with the importance-driven distribution, as the
// distribution saw it: where it is, how it scatters, its power before the 1 / P_k, its
// estimated contribution phi_k to the image, P_k and whether it was kept.
struct VplCandidate {
    Vec3 p, n;
    Vec3 wo;  // toward the previous vertex of its light path
    std::optional<SurfaceBsdf> bsdf;
    Rgb throughput;  // light-path throughput (energy over the sampling densities)
    int path_length = 0;
    double phi = 0;  // mean luminance of its contribution over the importance records
    double keep_probability = 1;
    bool kept = true;
};

struct VplSelection {
    std::vector<VplCandidate> candidates;
    uint64_t light_paths = 0;          // N_L: each term carries 1 / N_L
    int importance_records = 0;        // N_R: phi_k averages over this many records
    double record_distance_clamp = 0;  // the records' connections use max(d, this)
};

// One iteration's photon beams as the beam lookup sees them (upbp with photon beams), for the
// benchmark of the lookup (bench/beam_lookup.cpp).
struct PhotonBeamInspection {
    std::vector<BeamLine> lines;
    double radius = 0;
};

// Upper bounds of the sizes of vertex_cm.cpp's stored records, for the per-iteration memory
// estimate (core/render/iteration_memory.cpp); vertex_cm.cpp checks them with static_assert,
// so a record that grows past its bound fails the build instead of the estimate.
inline constexpr size_t kLightVertexBytesBound = 192;  // a stored light vertex (LightVertex)
inline constexpr size_t kJoint2VertexBytesBound = 20;  // J2's state of one (Joint2Vertex)
inline constexpr size_t kPhotonBeamBytesBound = 128;   // a photon beam (PhotonBeam)
inline constexpr size_t kBeamReplayBytesBound = 24;    // its replay state, where it has one
inline constexpr size_t kLightRayBytesBound = 104;     // a J2 light ray (LightRay)

// The buffers of an iteration (light vertices, splats, merging grids), kept from one
// iteration to the next (vertex_cm.cpp).
namespace vcm_detail {
struct IterationStorage;  // vcm_iteration.h
}  // namespace vcm_detail

class VertexConnectionMerging final : public Integrator {
  public:
    explicit VertexConnectionMerging(const BidirectionalConfig& config);
    ~VertexConnectionMerging() override;

    void render_iteration(const Scene& scene, const IterationKey& key, AccumulationBuffer& target,
                          TechniqueLayers* layers, RenderStats& stats) const override;

    const BidirectionalConfig& config() const { return config_; }

    // The importance-driven distribution's view of one iteration (mode Vpl with
    // vpl_importance): every candidate with its estimate and draw. It repeats the iteration's
    // light and record passes, so its numbers are those render_iteration uses; for tests and
    // diagnostics.
    VplSelection inspect_vpl_selection(const Scene& scene, const IterationKey& key) const;
    // The photon beams of one iteration (upbp with photon beams; empty otherwise), as the
    // iteration builds them; for benchmarks.
    PhotonBeamInspection inspect_photon_beams(const Scene& scene, const IterationKey& key) const;

  private:
    BidirectionalConfig config_;
    // Reused by each render_iteration (cleared, capacity kept), so that iterations after the
    // first do not fault in hundreds of MB of fresh pages; calls on one integrator from
    // several threads take turns.
    mutable std::mutex storage_mutex_;
    mutable std::unique_ptr<vcm_detail::IterationStorage> storage_;
};

}  // namespace render
