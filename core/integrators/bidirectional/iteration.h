#pragma once

// One iteration of the bidirectional family (lt, bpt, ppm, bpm, vcm, upbp) or of many-light
// rendering (vpl, ic): the shared core that traces and stores the light subpaths, and the
// connections, merges and beams that join them to eye subpaths. Not an interface beyond
// core/integrators: the integrators (bidirectional_integrator.h,
// many_lights/many_light_integrator.h) drive it.

#include <algorithm>
#include <climits>
#include <cmath>
#include <cstddef>
#include <optional>
#include <span>
#include <utility>
#include <vector>

#include "core/image/technique_layers.h"
#include "core/integrators/bidirectional/iteration_plan.h"
#include "core/integrators/bidirectional/iteration_storage.h"
#include "core/integrators/bidirectional/subpath.h"
#include "core/integrators/bidirectional/vcm_mis.h"
#include "core/integrators/direct_light.h"
#include "core/integrators/importance_lookup.h"
#include "core/integrators/importance_mixture.h"
#include "core/integrators/importance_optimise.h"
#include "core/integrators/importance_record.h"
#include "core/integrators/integrator.h"
#include "core/integrators/joint_segment.h"
#include "core/integrators/medium_segment.h"
#include "core/integrators/pixel_loop.h"
#include "core/integrators/volume_light_sampling.h"
#include "core/integrators/vpl_distribution.h"
#include "core/math/constants.h"
#include "core/media/medium_interface.h"
#include "core/scene/scene.h"
#include "core/scene/volume_emitter.h"
#include "core/util/function_ref.h"

namespace render {

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

namespace bidirectional {

// Light paths draw from streams disjoint from the pixels' (stream = pixel index).
inline constexpr uint64_t kLightStreamBase = uint64_t(1) << 62;
// Importance records (camera points of the importance-driven VPL distribution) and the
// acceptance draws of VPL candidates use streams of their own.
inline constexpr uint64_t kRecordStreamBase = kLightStreamBase + (uint64_t(1) << 60);
inline constexpr uint64_t kAcceptStreamBase = kLightStreamBase + (uint64_t(2) << 60);
inline constexpr uint64_t kImportanceStreamBase = kLightStreamBase + (uint64_t(3) << 60);
// Importance caching: the records of the screen grid, and their tables' shadow rays.
inline constexpr uint64_t kIcRecordStreamBase = kLightStreamBase + (uint64_t(4) << 60);
inline constexpr uint64_t kIcTableStreamBase = kLightStreamBase + (uint64_t(5) << 60);
// Photon beams in grid media: the ratio-tracking transmittance of a long beam's earlier pieces,
// one stream per (light path, segment), so the light path's own numbers are not consumed.
inline constexpr uint64_t kPhotonBeamStreamBase = kLightStreamBase + (uint64_t(9) << 60);
// bpt with ic connections: records at the first non-delta vertices of each record path (eye
// vertices t = 2, 3, 4), so that eye vertices past the first find records that saw what they see.
inline constexpr int kIcConnectionRecordsPerPath = 3;
// Importance caching keeps its tables (four doubles per record and VPL) below this size; a
// denser record grid is thinned to fit (docs/reference/algorithms.md).
inline constexpr double kIcTableBytes = 512.0 * 1024 * 1024;
// Light paths are traced in fixed chunks whose vertices are kept, and whose splats are added,
// in chunk order, so the image does not depend on the number of threads.
inline constexpr uint64_t kLightPathChunk = 256;
// Chunks traced but not yet gathered, per thread: enough that no thread waits for a slow chunk
// to be gathered, few enough that their buffers stay small next to the light vertices.
inline constexpr int kLightChunksInFlightPerThread = 4;

// The light tracer's splats (t = 1) added to the image and its layers (non-finite ones counted
// and dropped). The light pass hands them over in chunk order and before the eye pass's
// estimates, so that each pixel's sum is the same whatever the number of threads. With `active`
// (adaptive sampling), a splat into an inactive pixel is dropped: that pixel takes no part in
// the iteration, so its sum and its count stay those of its active iterations
// (docs/reference/adaptive-sampling.md, "The bidirectional family").
SplatSink splats_into(AccumulationBuffer& target, TechniqueLayers* layers, RenderStats& stats,
                      const uint8_t* active = nullptr);

// One iteration as the integrators run it, on `kept`'s buffers: the light pass (skipped in a
// scene without lights), its splats into target and layers; prepare(iteration, stats), what the
// integrator builds over the stored light vertices (importance caches, the VPL selection); then
// eye_path(iteration, pixel, stats, sink) for every pixel, or with `active` (one entry per
// pixel) for the active pixels only. The light pass and prepare do not depend on `active`:
// an active pixel's value is the one it has without the mask.
template <class Prepare, class EyePath>
void run_iteration(const IterationPlan& plan, const Scene& scene, const IterationKey& key,
                   KeptStorage& kept, AccumulationBuffer& target, TechniqueLayers* layers,
                   RenderStats& stats, const uint8_t* active, Prepare&& prepare,
                   EyePath&& eye_path);

// Where a pass hands a contribution: s light vertices (the eye's count is the caller's).
using ContributionSink = FunctionRef<void(int s, const Rgb& contribution)>;

// One iteration of the bidirectional family or of many-light rendering: what the light pass and
// the eye pass share. Its passes live in files of their own (light_pass.cpp, connections.cpp,
// joint_connections.cpp, merging.cpp, beams.cpp, eye_pass.cpp, vpl_selection.cpp,
// importance_caching.cpp); its large buffers are `storage`'s, cleared by the constructor.
class Iteration {
  public:
    Iteration(const IterationPlan& plan, const Scene& scene, const IterationKey& key,
              IterationStorage& storage);

    // Traces the light paths in chunks, in parallel, and gathers each chunk in chunk order: its
    // vertices into light_vertices_ (and the merging grids' positions), its splats to
    // add_splats, on one thread at a time.
    void trace_light_paths(RenderStats& stats, const SplatSink& add_splats);
    // vpl with the importance-driven distribution: keeps each light vertex with its
    // probability P_k (dividing its throughput by P_k) and drops the others.
    void select_vpls(RenderStats& stats, VplSelection* inspection = nullptr);
    // ic, and bpt with ic connections: traces the records of the screen grid and builds their
    // tables over the light vertices (bpt: those of the first plan_.ic_light_path_count paths), the
    // lookup tree and the conservative fallback.
    void build_importance_cache(RenderStats& stats);
    Rgb trace_eye_path(uint64_t pixel, RenderStats& stats, const LayerSink& sink) const;

    // The building blocks of an eye pass (this one's and the many-light integrator's).
    // A pixel's eye subpath: its random numbers, its first ray and its state at the camera.
    Ray start_eye_path(uint64_t pixel, Rng& rng, SubpathState& state) const;
    // The eye subpath left the scene along `ray` after the segment `seg`: completes its MIS
    // quantities and passes to `add` what each background light sends back along it,
    // MIS-weighted (s = 0).
    void escaped_emission(SubpathState& state, const Ray& ray, const SampledSegment& seg,
                          FunctionRef<void(const Rgb&)> add) const;
    // Traces the next segment of a subpath and, unless it left the scene, builds the vertex
    // it ends at and completes the MIS quantities' conversion (`arrive`). `traced`: closest
    // hits along `ray` a gather's walk found already (sample_segment reuses them).
    std::optional<SubpathVertex> next_vertex(const Ray& ray, TransportMode mode, Rng& rng,
                                             SubpathState& state, RenderStats& stats,
                                             SampledSegment& segment,
                                             const TracedPieces* traced = nullptr) const;
    bool sample_scattering(const SubpathVertex& v, const Vec3& wo, Rng& rng, SubpathState& state,
                           Ray& ray) const;
    // The emission `le` the eye subpath found on `light` (at `hit_point` for a finite light),
    // MIS-weighted (s = 0). Callers look it up with Light::radiance_at for a surface hit, so
    // emitters whose density or texture depends on the primitive read the hit's own.
    // `arrival_medium`: the medium the eye subpath reached the light in.
    Rgb emission(const Light* light, const SubpathState& state, const LightRadiance& le,
                 const Vec3& hit_point, const Medium* arrival_medium) const;
    // The eye subpath's collision estimate of the emission at v, a vertex in an emitting medium
    // just reached (s = 0 with the medium as the light), MIS-weighted, without the throughput
    // before the segment (state.source_throughput holds it).
    Rgb medium_emission(const SubpathState& state, const Vertex& v) const;
    Rgb direct_illumination(const SubpathState& state, const SubpathVertex& v, const Vec3& wo,
                            Rng& rng, RenderStats& stats) const;
    // The VPL estimator's term for one light vertex at eye vertex v (without the eye and light
    // throughputs): f_v G f_light V / N_L, with G's distance clamped at sqrt(clamp2).
    Rgb vpl_connection(const LightVertex& light_vertex, const Vertex& v, const Vec3& wo,
                       float clamp2, Rng& rng, RenderStats& stats) const;
    // Importance caching at eye vertex v: light vertices drawn from the mixtures of v's
    // nearest records; each drawn vertex's `term` (its contribution without the eye
    // throughput), weighted by MIS between the four techniques and divided by its probability,
    // is passed to `add` with the number of light vertices s of its path.
    void draw_from_importance_caches(const Vertex& v, int eye_length, Rng& rng,
                                     FunctionRef<Rgb(const LightVertex&)> term,
                                     ContributionSink add) const;

    const IterationPlan& plan() const { return plan_; }
    const IterationKey& key() const { return key_; }
    const BlockVector<LightVertex>& light_vertices() const { return light_vertices_; }

    // The records' connections are clamped at 1 % of the scene radius at least, so that a VPL
    // lying on a record cannot take all the importance: this shapes P_k only, never the bias.
    float record_clamp2() const {
        const double radius = scene_.bounding_sphere().radius;
        return std::max(plan_.vpl_clamp2, float(1e-4 * radius * radius));
    }

  private:
    // Solid-angle density, per unit pixel area, of the camera producing world direction `dir`
    // from lens point `origin` (the report's camera pdf with the image plane measured in pixels).
    float camera_pixel_pdf_w(const Vec3& origin, const Vec3& dir) const {
        return camera_.direction_pdf_w(origin, dir) * float(plan_.pixel_count);
    }

    bool generate_light_sample(Rng& rng, SubpathState& state, Ray& ray) const;
    // A light subpath starting at a point of an emitting medium (docs/design/media.md, "Emitting
    // media as lights"), picked with probability pick_probability.
    bool generate_volume_light_sample(const VolumeEmitter& emitter, float pick_probability,
                                      Rng& rng, SubpathState& state, Ray& ray) const;
    // rays, joint2: where J2 keeps the path's light rays and the state of its stored vertices
    // (null without J2).
    void trace_light_path(uint64_t path_index, std::vector<LightVertex>& vertices,
                          std::vector<Splat>& splats, RenderStats& stats,
                          std::vector<LightRay>* rays = nullptr,
                          std::vector<Joint2Vertex>* joint2 = nullptr,
                          std::vector<LightVertexMedia>* arrival_media = nullptr) const;
    // Light vertex i's media (empty without the camera's medium rule, which never reads them).
    LightVertexMedia media_of(uint32_t i) const {
        return plan_.camera_medium_rule ? light_vertex_media_[i] : LightVertexMedia{};
    }
    Link link(const Ray& ray, const Medium* medium, bool start_in_medium, bool end_in_medium,
              Rng& rng, RenderStats& stats) const;
    // The segment just traced reached a boundary against its declaration, on the way or at its
    // end (medium_interface.h).
    static bool arrives_against_declaration(const SampledSegment& seg, const Ray& ray);
    // The medium a light subpath from `light` starts in: an area light's side, a nested
    // reference, vacuum for infinite lights.
    static const Medium* light_start_medium(const Light& light) {
        return light.is_finite() ? light.medium : nullptr;
    }
    Rgb visibility(const Link& link, const Ray& ray, RenderStats& stats) const;
    void connect_to_camera(const SubpathState& state, const SubpathVertex& v, const Vec3& wo,
                           Rng& rng, std::vector<Splat>& splats, RenderStats& stats) const;
    // Next-event estimation's MIS-weighted contribution at v (without the eye throughput) for
    // the light sample dl, visibility included; joint: v was sampled by J1 at s = 1 toward the
    // light point (the weight is that technique's).
    Rgb direct_contribution(const MisQuantities& eye_mis, const SubpathVertex& v, const Vec3& wo,
                            const DirectLightSample& dl, Rng& rng, RenderStats& stats,
                            bool joint = false) const;
    // light_joint2: the light vertex's J2 state (joint2_of); light_media: its media (media_of),
    // which the camera's medium rule needs.
    Rgb connect_vertices(const LightVertex& light_vertex, const Joint2Vertex& light_joint2,
                         const SubpathVertex& v, const Vec3& wo, const MisQuantities& eye_mis,
                         Rng& rng, RenderStats& stats,
                         const LightVertexMedia& light_media = {}) const;
    // The J2 state of stored light vertex i (none without J2: the side array is empty then).
    const Joint2Vertex& joint2_of(uint32_t i) const {
        static const Joint2Vertex none;
        return plan_.joint2 ? joint2_vertices_[i] : none;
    }
    // Joint connections for the eye segment about to be traced along `ray` from the eye
    // subpath's last vertex: each light vertex in [first, end) joined through a medium vertex
    // of the segment's first piece, sampled toward it; each passed to add(s, contribution).
    // [rays_first, rays_end): the light path's rays for J2 (light_rays_; empty: none).
    void joint_connections(const Ray& ray, const SubpathState& state, uint32_t first, uint32_t end,
                           uint32_t rays_first, uint32_t rays_end, Rng& rng, RenderStats& stats,
                           ContributionSink add) const;
    // Eye subpaths arriving at x in one piece from state.origin (|cos| cos_in at x, distance
    // density distance_pdf): the J2 term of the junction whose light ray would start at x (at a
    // light's point should the path end there, or at a scattering vertex of the light subpath),
    // which every technique with x on the light side counts (vcm_mis.h, add_eye_joint2_term).
    void add_arrival_joint2_term(MisQuantities& mis, const SubpathState& state, const Vec3& x,
                                 float cos_in, float distance_pdf) const;
    // J2 of the junction toward the camera at eye vertex v, joined through `link` (one piece)
    // to the light-side point y: v resampled on the light ray from y toward it, its successor
    // toward the camera by J1 (vcm_mis.h, eye_joint2_term); 0 where J2 cannot resample v.
    float eye_joint2_toward(const MisQuantities& eye_mis, const SubpathVertex& v, const Vec3& y,
                            const Link& link) const;
    // The eye subpath arrived at v: its connection term gains the J1 technique of the junction
    // toward the camera (vcm_mis.h, include_joint_junction).
    void include_joint_junction(MisQuantities& mis, const SubpathState& state,
                                SubpathVertex& v) const;
    // A connection's MIS-weighted contribution before visibility (f_eye G f_light w, without
    // the subpaths' throughputs) and the segment that decides its visibility; empty when it is
    // zero whatever the visibility.
    struct ConnectionTerms {
        ConnectionGeometry geometry;
        Rgb unoccluded;
        Ray ray;
        Link link;
    };
    // joint: v was sampled by the J1 technique, or both vertices by J2 (the weight is that
    // technique's).
    std::optional<ConnectionTerms> connection_terms(
        const LightVertex& light_vertex, const Joint2Vertex& light_joint2, const SubpathVertex& v,
        const Vec3& wo, const MisQuantities& eye_mis, Rng& rng, RenderStats& stats,
        JointKind joint = JointKind::None, const LightVertexMedia& light_media = {}) const;
    // J2: q = p_B2 / p_distance of the light-side vertex `x` of a junction, resampled on the
    // light ray from `light_point` (a light's point or a scattering vertex; x's density from there:
    // light_ray_pdf, 0 where J2 cannot resample it), the eye ray from `eye_origin` through
    // `eye_side`; 0 without J2.
    float light_joint2_ratio(const Vec3& light_point, const Vec3& x, float light_ray_pdf,
                             const Vec3& eye_origin, const Vec3& eye_side) const {
        if (!plan_.joint2 || !(light_ray_pdf > 0)) return 0.0f;
        return joint2_pdf_l(scene_.bounding_sphere(), light_point, x, eye_origin, eye_side) /
               light_ray_pdf;
    }
    // J2 in joint_connections: the vertex at the end of one of the light path's rays, resampled
    // on it by B2 toward the eye ray (nullopt: none), with the MIS quantities next_vertex would
    // have given it; joint2 receives its J2 state.
    std::optional<LightVertex> resample_on_light_ray(const LightRay& light_ray,
                                                     const Vec3& eye_origin,
                                                     const Vec3& eye_direction,
                                                     Joint2Vertex& joint2, Rng& rng) const;
    // J2: the light ray that `ray` starts (after generate_light_sample or sample_scattering
    // with `state`), whose end vertex would be reached after path_length segments; nothing
    // where J2 cannot resample on it (not a homogeneous medium).
    void record_light_ray(const Ray& ray, const SubpathState& state, int path_length,
                          std::vector<LightRay>& rays, RenderStats& stats) const;
    Rgb merge(const Vertex& v, const Vec3& wo, const SubpathState& state) const;
    // J1 of the junction whose eye-side vertex is the merge vertex v (sampled from the eye's
    // previous vertex toward the light vertex's predecessor) over its plain connection; 0
    // without joint connections or where that junction has none (vcm_mis.h, weight_merge).
    float merge_joint_ratio(const LightVertex& light_vertex, const Vertex& v) const;
    // Whether the predecessor of a light subpath's vertex (reached after path_length segments)
    // can be the light-side vertex of a J1 junction: a scattering vertex, or the light's own
    // point when the light is finite (J1 at s = 1).
    static bool joint_light_side(int path_length, bool finite_light) {
        return path_length >= 2 || (path_length == 1 && finite_light);
    }
    // Query beams (P-B2D): the photon points within the beam radius of the eye segment about
    // to be traced along `ray`, over every piece in a medium up to the first surface that is
    // not a null boundary (the long query), each gathered at its projection on the segment.
    // The walk's closest hits go to `traced` (when given) for the segment's sampling.
    Rgb query_beams(const Ray& ray, const SubpathState& state, Rng& rng, RenderStats& stats,
                    TracedPieces* traced = nullptr) const;
    // The pieces of an eye segment along `ray`, walked as sample_segment does without sampling
    // a distance, up to the first surface that is not a null boundary: visit(medium, piece,
    // t_end, before, transmittance) for each piece in a medium, with the MIS densities and the
    // transmittance of the pieces before it. The walk of query_beams and photon_beams.
    template <typename Visit>
    void for_each_eye_medium_piece(const Ray& ray, const SubpathState& state, Rng& rng,
                                   RenderStats& stats, const std::optional<Aabb>& reach,
                                   TracedPieces* traced, Visit&& visit) const;
    // Photon beams (B-B1D). Light subpaths: the beams of the segment just sampled along `ray`
    // from the subpath `from` (its state before the segment), appended to the thread's staging
    // buffer; `piece` counts the path's pieces so far.
    void emit_photon_beams(const Ray& ray, const SubpathState& from, const SampledSegment& seg,
                           uint64_t path_index, uint32_t& piece, Rng& rng,
                           RenderStats& stats) const;
    // Puts the staged beams in order and builds their lookup.
    void build_photon_beams();
    // Eye subpaths: the photon beams within the beam radius of the eye segment about to be
    // traced along `ray` (its pieces in media up to the first surface that is not a null
    // boundary: the long query), each gathered at its closest approach.
    Rgb photon_beams(const Ray& ray, const SubpathState& state, Rng& rng, RenderStats& stats,
                     TracedPieces* traced = nullptr) const;
    // Both gathers over one walk of the eye segment's pieces (each normalised as the two
    // functions above normalise it): one closest hit and one transmittance per piece instead
    // of two. The sums are those of query_beams and photon_beams, in the same order.
    void both_beams(const Ray& ray, const SubpathState& state, Rng& rng, RenderStats& stats,
                    Rgb& query_sum, Rgb& photon_sum, TracedPieces* traced = nullptr) const;
    // Where the walk of an eye segment can gather a photon point (points) or a photon beam
    // (beams): the lookups' boxes, grown by the drift of the pieces' origins over the walk's
    // null-boundary crossings. The walk stops at a piece whose line misses it (saving the closest
    // hits of eye segments that never come near a medium, and of the pieces after the last one
    // in a medium). Empty (walk everything) when a grid medium makes the walk draw numbers.
    std::optional<Aabb> gather_reach(bool points, bool beams) const;
    // One piece's part of each gather (unnormalised), added to sum.
    void query_beams_in_piece(const Ray& ray, const SubpathState& state, const Medium* medium,
                              const Ray& piece, float t_end, const SegmentDensityBuilder& before,
                              const Rgb& transmittance, Rng& rng, Rgb& sum) const;
    void photon_beams_in_piece(const Ray& ray, const SubpathState& state, const Medium* medium,
                               const Ray& piece, float t_end, const SegmentDensityBuilder& before,
                               const Rgb& transmittance, Rng& rng, Rgb& sum) const;
    // B-B1D terms of a light vertex v (reached from wo) sampled from the camera side along
    // direction d with density pdf (without its distance density); 0 without the technique.
    float light_photon_beam_term(const Vertex& v, const Vec3& wo, const Vec3& d, float pdf) const {
        return light_photon_beam_term(v.photon_beam, v.arrival_distance, v.sigma_t, wo, d, pdf);
    }
    float light_photon_beam_term(const LightVertex& v, const Vec3& wo, const Vec3& d,
                                 float pdf) const {
        return light_photon_beam_term(v.photon_beam(), v.arrival_distance(), v.sigma_t(), wo, d,
                                      pdf);
    }
    // The same of a vertex's photon-beam quantities (Vertex).
    float light_photon_beam_term(float photon_beam, float arrival_distance, float sigma_t,
                                 const Vec3& wo, const Vec3& d, float pdf) const;
    // Sets v's photon-beam quantities on arrival (a medium vertex reached by `seg`).
    void set_photon_beam_quantities(Vertex& v, const SampledSegment& seg, TransportMode mode) const;
    // Where photon beams live (docs/design/media.md, "Photon beams in grid media"): long beams in
    // every medium (ratio tracking estimates their transmittance), short ones where their weight is
    // known: the sampled distance's pass weight exactly (homogeneous media, grey grids), or in a
    // chromatic grid the sampling walk's own pass weight, replayed (replays_walk), on segments
    // of one piece. The weights use the same predicate, so a vertex no beam can reach has
    // M_B = 0 in every technique.
    bool beam_segment(const SegmentDensities& d) const {
        return !plan_.short_photon_beams || d.short_beam_support;
    }
    // A short beam in `medium` carries the replayed walk's pass weight (a chromatic grid).
    bool replays_walk(const Medium* medium) const {
        return plan_.short_photon_beams && !medium->is_homogeneous() &&
               !medium->pass_weight_is_one();
    }
    static std::optional<ConnectionGeometry> connection_geometry(const LightVertex& light_vertex,
                                                                 const Vertex& v, const Vec3& wo);
    // An importance record: the first non-delta vertex of a camera path through a random
    // image position, with the eye throughput that reaches it.
    struct Record {
        SubpathVertex vertex;
        Vec3 wo;
        Rgb throughput;
        int path_length;
        float distance;  // along the camera path (for the record's footprint)
        Vec3 camera_direction;
        MisQuantities mis;   // of the eye subpath ending at the record (ic connections' weights)
        Vec3 camera_origin;  // the camera ray's lens point (the camera position for a pinhole)
    };
    std::optional<Record> trace_record(uint64_t index, RenderStats& stats) const;
    // The record of the camera ray through image position `position` (in pixels).
    std::optional<Record> trace_record_at(Vec2 position, Rng& rng, RenderStats& stats) const;
    // The records at the first `count` non-delta vertices of the camera path through
    // `position`, appended to `out`.
    void trace_records_at(Vec2 position, int count, Rng& rng, RenderStats& stats,
                          std::vector<Record>& out) const;
    // The four tables of one importance-caching record over the first ic_vertex_count_
    // light vertices.
    IcRecordTables record_tables(const Record& r, float radius, std::span<const uint8_t> mask,
                                 Rng& rng, RenderStats& stats) const;
    // phi_k of every light vertex: the luminance of its contribution averaged over the
    // iteration's importance records (escaped records count as zero).
    std::vector<double> estimate_vpl_importance(RenderStats& stats) const;

    const IterationPlan plan_;
    const Scene& scene_;
    IterationKey key_;
    const PerspectiveCamera& camera_;
    VcmMis mis_;
    // The importance caches' light vertices: a prefix of light_vertices_, set by
    // build_importance_cache.
    size_t ic_vertex_count_ = 0;

    IterationStorage& storage_;
    BlockVector<LightVertex>& light_vertices_;
    std::vector<uint32_t>& path_ends_;            // light_vertices_ of path p: [ends[p-1], ends[p])
    std::vector<LightRay>& light_rays_;           // with J2 (else empty)
    std::vector<uint32_t>& ray_ends_;             // light_rays_ of path p end here (with J2)
    BlockVector<Joint2Vertex>& joint2_vertices_;  // of light vertex i, with J2 (else empty)
    BlockVector<LightVertexMedia>& light_vertex_media_;  // of light vertex i, under the rule
    // Importance caching: one table set per record, the records' lookup tree (same order), the
    // conservative fallback over every cached vertex, the sample counts, the weighting and the
    // lookup.
    std::vector<IcRecordTables> ic_tables_;
    IcRecordTree ic_tree_;
    ImportanceTable ic_fallback_;
    IcSampleCounts ic_samples_{};
    IcWeighting ic_weighting_;
    IcLookupSettings ic_lookup_;
    // Merging: surface and medium light vertices in separate grids (photons merge only with
    // eye vertices of their own kind); *_index_ maps a grid point to its light vertex. The
    // surface grid reads its points' positions from the light vertices; the medium points'
    // positions are kept for the query beams' lookup too.
    std::vector<Vec3>& medium_positions_;
    std::vector<uint32_t>&surface_index_, &medium_index_;
    HashGrid &surface_grid_, &medium_grid_;
};

template <class Prepare, class EyePath>
void run_iteration(const IterationPlan& plan, const Scene& scene, const IterationKey& key,
                   KeptStorage& kept, AccumulationBuffer& target, TechniqueLayers* layers,
                   RenderStats& stats, const uint8_t* active, Prepare&& prepare,
                   EyePath&& eye_path) {
    std::lock_guard lock(kept.mutex);
    Iteration iteration(plan, scene, key, kept.storage);
    if (!scene.lights().empty() || !scene.volume_lights().empty()) {
        iteration.trace_light_paths(stats, splats_into(target, layers, stats, active));
        prepare(iteration, stats);
    }
    for_each_pixel(
        scene.camera().width(), scene.camera().height(), target, stats, active,
        [&](uint64_t pixel, RenderStats& local) {
            return eye_path(std::as_const(iteration), pixel, local, LayerSink{layers, pixel});
        });
}

}  // namespace bidirectional
}  // namespace render
