#pragma once

// The internals of the bidirectional family, shared by vertex_cm.cpp (light and eye
// subpaths, connections, merges), vcm_beams.cpp (query and photon beams) and
// vcm_many_lights.cpp (VPLs and importance caching): the subpath state, the vertices, and
// the Iteration that one render_iteration call builds. Not an interface: include it only
// from those files.

#include "core/integrators/vertex_cm.h"

#include <algorithm>
#include <climits>
#include <cmath>
#include <cstddef>
#include <functional>
#include <optional>
#include <span>
#include <vector>

#include "core/base/scene_limits.h"
#include "core/integrators/beam_grid.h"
#include "core/integrators/beams_along_ray.h"
#include "core/integrators/direct_light.h"
#include "core/integrators/hash_grid.h"
#include "core/integrators/importance_lookup.h"
#include "core/integrators/importance_mixture.h"
#include "core/integrators/importance_optimise.h"
#include "core/integrators/importance_record.h"
#include "core/integrators/joint_segment.h"
#include "core/integrators/medium_segment.h"
#include "core/integrators/merge_radius.h"
#include "core/integrators/pixel_loop.h"
#include "core/integrators/points_along_ray.h"
#include "core/integrators/vcm_mis.h"
#include "core/integrators/volume_light_sampling.h"
#include "core/integrators/vpl_distribution.h"
#include "core/materials/surface_bsdf.h"
#include "core/math/constants.h"
#include "core/media/medium.h"
#include "core/media/medium_interface.h"
#include "core/sampling/half_line_equiangular.h"
#include "core/scene/volume_emitter.h"
#include "core/util/block_vector.h"

namespace render {
namespace vcm_detail {

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
// denser record grid is thinned to fit (docs/algorithms.md).
inline constexpr double kIcTableBytes = 512.0 * 1024 * 1024;
// Light paths are traced in fixed chunks whose vertices are kept, and whose splats are added,
// in chunk order, so the image does not depend on the number of threads.
inline constexpr uint64_t kLightPathChunk = 256;
// Chunks traced but not yet gathered, per thread: enough that no thread waits for a slow chunk
// to be gathered, few enough that their buffers stay small next to the light vertices.
inline constexpr int kLightChunksInFlightPerThread = 4;

// A subpath being extended: the throughput and the report's recursive MIS quantities.
struct SubpathState {
    Rgb throughput;
    float initial_luminance = 1;  // for Russian roulette relative to the start
    int path_length = 1;          // segments traced so far (the report's "path length")
    bool is_finite_light = true;  // light subpaths: the origin is a finite point
    bool specular_path = true;    // eye subpaths: every scattering so far was a delta lobe
    MisQuantities mis;
    const Medium* medium = nullptr;  // where the next segment starts (null: vacuum)
    bool in_medium = false;          // the next segment starts at a medium vertex
    // Joint connections: the vertex the next segment starts at (the camera or the light point
    // at first), the position it was reached from, its J1 distance density (Vertex) and
    // whether it scatters in a medium; on light subpaths, the connection term its scatter
    // added to dVC, completed at the next arrival (vcm_mis.h).
    Vec3 origin, origin_previous;
    float origin_joint_pdf = 0;
    bool origin_in_medium = false;
    float carried_connection = 0;
    // Joint (J2) connections on the light path's rays: the position before origin_previous, the
    // light-ray distance densities of the origin vertex and of its predecessor (Joint2Vertex);
    // on eye subpaths the J1 share of the connection term the last scatter added to dVC
    // (vcm_mis.h, carried_eye_joint2_term), completed at the next arrival
    // (add_arrival_joint2_term).
    Vec3 origin_previous2;
    float origin_light_ray_pdf = 0;
    float origin_previous_light_ray_pdf = 0;
    float carried_eye_joint2 = 0;
    // Light subpaths with query beams: the factor of the P-B2D term of the vertex the next
    // segment starts at, added at the next arrival (vcm_mis.h, add_query_beam_term).
    float carried_query_beam = 0;
    // With photon beams (either subpath): the B-B1D term of the vertex the next segment starts
    // at, added at the next arrival (vcm_mis.h, add_photon_beam_term).
    float carried_photon_beam = 0;
    // Eye subpaths in scenes with emitting media: after a segment that ended at a vertex in an
    // emitting medium, the throughput before the segment times its source weight
    // (SampledSegment::source_weight); times sigma_a L_e there, the collision estimate of the
    // emission (medium_emission).
    Rgb source_throughput;
};

// A scattering vertex of a subpath: a surface point with a BSDF, or a point in a medium where
// a phase function scatters. Medium vertices have no normal: cosines are 1, and the vertex
// measure is volume instead of area (core/integrators/vcm_mis.h).
struct Vertex {
    // The medium and the position first: with what a merge reads of a stored light vertex,
    // they lie in its first cache line (LightVertex), and a merge in a medium reads both.
    const Medium* medium = nullptr;  // the medium the path arrived in
    Vec3 p;
    Vec3 n;  // geometric normal; zero in a medium
    const Shape* shape = nullptr;
    // std::optional's interface, 8 bytes smaller; the next float fills its tail padding.
    [[no_unique_address]] OptionalSurfaceBsdf bsdf;
    // Eye subpaths with query beams (P-B2D): this medium vertex's merge factor of that
    // technique, VcmMis::query_beam_factor of the distance density that reached it.
    float query_beam = 0;
    const PhaseFunction* phase = nullptr;
    // Joint connections: the position the subpath reached this vertex from, and (a medium
    // vertex reached without crossing a boundary) the distance density of reaching it, with
    // which a J1 technique's density compares; 0 where no J1 technique samples this vertex.
    Vec3 previous;
    float joint_distance_pdf = 0;
    // With photon beams, at a medium vertex: the distance density of the segment that reached
    // it, the medium's mean sigma_t there, and the vertex's own part of its B-B1D term
    // (VcmMis::photon_beam_light_factor or photon_beam_eye_factor by subpath; 0 where the
    // technique cannot sample it: on a light subpath reached by
    // a segment that cannot carry a beam).
    float arrival_distance = 0;
    float sigma_t = 0;
    float photon_beam = 0;

    bool in_medium() const { return phase != nullptr; }
    bool has_non_delta() const { return phase || bsdf->bsdf().has_non_delta(); }
    bool has_delta() const { return !phase && bsdf->bsdf().has_delta(); }
    // |cos| with the geometric normal (densities) and with the shading normal (throughput).
    float cos(const Vec3& w) const { return phase ? 1.0f : abs_dot(n, w); }
    float shading_cos(const Vec3& w) const { return phase ? 1.0f : bsdf->abs_cos_shading(w); }
    BsdfEvaluation evaluate(const Vec3& wo, const Vec3& wi) const {
        if (!phase) return bsdf->evaluate(wo, wi);
        const float p = phase->p(wo, wi);  // reciprocal and exactly sampled: both densities
        return BsdfEvaluation{Rgb(p), BsdfPdf{p, p}};
    }
    std::optional<BsdfSample> sample(const Vec3& wo, float u_lobe, Vec2 u) const {
        if (!phase) return bsdf->sample(wo, u_lobe, u);
        const PhaseSample ps = phase->sample(wo, u);
        if (!(ps.pdf_w > 0)) return std::nullopt;
        BsdfSample bs;
        bs.wi = ps.wi;
        bs.weight = Rgb(1.0f);
        bs.pdf_w = BsdfPdf{ps.pdf_w, ps.pdf_w};
        return bs;
    }
    // The medium on the side of direction d, for a path that arrived from wo: a surface keeps
    // the arrival medium on wo's side and has its shape's medium across (medium_interface.h).
    const Medium* medium_toward(const Vec3& wo, const Vec3& d) const {
        if (phase || dot(d, n) * dot(wo, n) > 0) return medium;
        return dot(d, n) < 0 ? shape->interior : shape->exterior;
    }
};

// Joint (J2) connections' state of a subpath vertex, which resample a light vertex on the light
// path's ray that reached it (docs/media.md): the position `previous` was reached from; this
// vertex's distance density from `previous` where J2 can resample it there (a medium vertex of
// a homogeneous medium reached in one piece from a scattering vertex or a finite light's point,
// on either subpath: 0 elsewhere), and the same of `previous`. Stored light vertices keep it in a
// side array indexed like them (IterationStorage::joint2_vertices), filled only with J2, so that
// the stored vertex does not pay for it when J2 is off.
struct Joint2Vertex {
    Vec3 previous2;
    float light_ray_pdf = 0;
    float previous_light_ray_pdf = 0;
};

// A vertex while its subpath is traced: the part a light vertex stores, J2's state, and on eye
// subpaths J1's ratio r of the junction toward the camera (whose eye-side vertex is `previous`;
// include_joint_junction), which J2's terms read.
struct SubpathVertex : Vertex {
    Joint2Vertex joint2;
    float camera_joint_ratio = 0;
};

// A stored light-subpath vertex with a non-delta BSDF or in a medium. A merge (Iteration::merge)
// tests path_length, evaluates the eye vertex's BSDF toward wo, weighs with mis and adds
// throughput, and in a medium reads vertex.medium and vertex.p: all in the first 40 + 20 bytes,
// which alignas(64) keeps in one cache line, so that a candidate costs one line (it cost two,
// with these fields behind the vertex). Only J1 (vertex.previous, finite_light) and photon beams
// (vertex.photon_beam, vertex.arrival_distance) read the third line. Still 192 bytes: three lines.
struct alignas(64) LightVertex {
    Vec3 wo;  // toward the previous vertex of the light subpath
    Rgb throughput;
    int path_length;
    MisQuantities mis;
    [[no_unique_address]] Vertex vertex;  // the next member fills its tail padding
    bool finite_light = true;             // the subpath starts at a point (J1 at s = 1 needs one)
};
static_assert(sizeof(Joint2Vertex) <= kJoint2VertexBytesBound,
              "Joint2Vertex grew: raise kJoint2VertexBytesBound (the memory estimate uses it)");
static_assert(sizeof(LightVertex) <= kLightVertexBytesBound,
              "LightVertex grew: raise kLightVertexBytesBound (the memory estimate uses it)");
static_assert(sizeof(LightVertex) % 64 == 0 &&
                  offsetof(LightVertex, vertex) + offsetof(Vertex, p) + sizeof(Vec3) <= 64,
              "a merge's fields of LightVertex (wo to vertex.p) no longer fit its first line");

// Which technique produced a connection: the plain one, J1 (the eye vertex sampled toward the
// light vertex) or J2 (the light vertex resampled on its light ray as well).
enum class JointKind { None, J1, J2 };

// Visibility and distance-sampling densities of a connection segment. Without media the
// segment is only tested for occlusion, and only once its contribution is known to be non-zero.
struct Link {
    SegmentDensities densities;
    Rgb transmittance{1.0f};
    bool traced = false;
    bool one_piece = false;  // traced, and no boundary crossed
};

// J1's density of the medium vertex x sampled on the half-line from `from` through it, toward
// the vertex `toward` (half_line_equiangular.h).
inline float joint_pdf_l(const Vec3& from, const Vec3& x, const Vec3& toward) {
    const Vec3 d = x - from;
    const float t = length(d);
    if (!(t > 0)) return 0.0f;
    return HalfLineEquiAngularSampler(from, d / t, toward).pdf_l(t);
}

struct Splat {
    uint32_t pixel;
    Rgb value;
    int light_vertices;  // s of the (s, t = 1) technique, for the per-technique layers
};

// A photon beam: one piece, in a medium (Iteration::beam_segment), of a light subpath's segment (up
// to the sampled distance for a short beam, to the next surface for a long one), with what its
// estimate and MIS weight need of the subpath at the segment's start (the beam's source).
struct PhotonBeam {
    uint64_t order = 0;  // (light path, piece) : the beams' order whatever the thread count
    BeamLine line;
    const Medium* medium = nullptr;
    // The source's throughput after scattering, times the pieces before this one: their
    // transmittance (long) or transmittance over pass probability (short).
    Rgb weight;
    float offset = 0;                     // from the source to the piece's start
    SegmentDensityBuilder before{false};  // the pieces before this one
    MisQuantities mis;                    // the subpath after scattering at the source
    float carried_query_beam = 0, carried_photon_beam = 0;
    int path_length = 0;  // segments of the light path with the beam's
    bool apply_distance = true;
};
static_assert(sizeof(PhotonBeam) <= kPhotonBeamBytesBound,
              "PhotonBeam grew: raise kPhotonBeamBytesBound (the memory estimate uses it)");

// A short photon beam in a chromatic grid (Iteration::replays_walk): the random state its
// sampling walk started with and that walk's t_max, replayed to the closest approach for its
// weight (Medium::replay_pass_weight). Kept in a side array indexed like the beams
// (IterationStorage::photon_beam_replays), filled only in an iteration where a beam replays, so
// that the beams of other scenes do not carry it.
struct BeamReplay {
    Rng rng{StreamKey{}};
    float t_max = 0;
};
static_assert(sizeof(BeamReplay) <= kBeamReplayBytesBound,
              "BeamReplay grew: raise kBeamReplayBytesBound (the memory estimate uses it)");

// One thread's photon beams while the light paths are traced (IterationStorage).
struct PhotonBeamStaging {
    std::vector<PhotonBeam> beams;
    // Empty until one of the thread's beams replays; from then on one per beam (the beams before
    // it get a default one that nothing reads).
    std::vector<BeamReplay> replays;
};

// The squared distance clamp of VPL connections in (1-based, global) iteration i; 0 unclamped.
inline double vpl_clamp_squared(const BidirectionalConfig& config, const Scene& scene,
                                uint64_t iteration) {
    if (!(config.vpl_clamp > 0)) return 0;
    double d = config.vpl_clamp * scene.bounding_sphere().radius;
    if (config.vpl_clamp_schedule == VplClampSchedule::Shrinking)
        d *= std::pow(double(iteration), -0.25);
    return d * d;
}

// The geometry of connecting eye vertex v (reached from wo) to a light vertex: the unit
// direction toward the light vertex, the squared distance, and both vertices' BSDF (or phase)
// evaluations along it. Empty when the vertices coincide or either side reflects nothing.
struct ConnectionGeometry {
    Vec3 d;
    float dist2;
    BsdfEvaluation eye, light;
};

// One chunk of light paths, from its tracing (in parallel with other chunks) to its gathering
// into the iteration's arrays (in chunk order).
// J2 (bpt --joint-connections all): a ray of a light path into a homogeneous medium, as it was
// before its distance sample: the emission ray from a finite light's point, or the ray a
// scattering vertex of the path sampled. J2 resamples the vertex at its end by B2, whatever the
// distance sample gave (a medium vertex, a surface, nothing); arriving there needs what
// next_vertex reads of the subpath (SubpathState) besides the ray.
struct LightRay {
    Vec3 origin, direction;          // the light point or vertex and the sampled unit direction
    Rgb throughput;                  // the subpath's, after the scattering (or emission)
    MisQuantities mis;               // the subpath's quantities after it
    const Medium* medium = nullptr;  // homogeneous
    float piece_end = 0;             // from origin to the first surface, null or not
    // The subpath's state at the ray's origin (SubpathState's fields of the same names).
    Vec3 origin_previous, origin_previous2;
    float origin_light_ray_pdf = 0, origin_previous_light_ray_pdf = 0;
    float carried_connection = 0;
    int path_length = 1;  // segments up to the resampled vertex
    bool origin_in_medium = false;
    bool finite_light = true;
};

static_assert(sizeof(LightRay) <= kLightRayBytesBound,
              "LightRay outgrew kLightRayBytesBound (vertex_cm.h): raise it");

struct LightChunk {
    uint64_t index = 0;
    std::vector<LightVertex> vertices;
    std::vector<uint32_t> path_sizes;           // vertices kept per path
    std::vector<LightRay> light_rays;           // with J2, else none
    std::vector<uint32_t> ray_counts;           // light rays per path, with J2
    std::vector<Joint2Vertex> joint2_vertices;  // one per vertex with J2, else none
    std::vector<Splat> splats;
    RenderStats stats;
};

using SplatSink = std::function<void(std::span<const Splat>)>;

// Buffers of an iteration that VertexConnectionMerging keeps from one iteration to the next.
struct IterationStorage {
    // In blocks: gathering a chunk appends without ever moving the vertices already there.
    BlockVector<LightVertex> light_vertices;
    std::vector<uint32_t> path_ends;
    // J2's light rays, and where each light path's end (like path_ends), with J2; else empty.
    std::vector<LightRay> light_rays;
    std::vector<uint32_t> ray_ends;
    // J2's state of each light vertex, indexed like light_vertices (with J2; else empty).
    BlockVector<Joint2Vertex> joint2_vertices;
    // The light pass's chunk buffers (a few per thread), reused from one iteration to the next.
    std::vector<std::unique_ptr<LightChunk>> light_chunks;
    std::vector<LightChunk*> free_light_chunks;
    std::mutex light_chunks_mutex;
    std::vector<Vec3> surface_positions, medium_positions;
    std::vector<uint32_t> surface_index, medium_index;
    HashGrid surface_grid, medium_grid;
    // Query beams: the medium light vertices as balls of the beam radius (made on first use:
    // it owns an Embree device).
    std::unique_ptr<PointsAlongRay> beam_lookup;
    // Photon beams: gathered per thread while the light paths are traced, then put in order
    // (photon_beams, and their lines for the lookup).
    tbb::enumerable_thread_specific<PhotonBeamStaging> photon_beam_staging;
    std::vector<PhotonBeam> photon_beams;
    // The beams' replay states, indexed like photon_beams, where a beam of the iteration
    // replays its walk (else empty).
    std::vector<BeamReplay> photon_beam_replays;
    std::vector<BeamLine> photon_beam_lines;
    // Their lookup: a uniform grid (measured 3-4x faster per query than the Embree BVH,
    // docs/media.md), or the BVH in an iteration where a beam leaves the scene's box (a beam
    // escaping through an unbounded medium: the grid would have to span it).
    UniformBeamGrid photon_beam_grid;
    std::unique_ptr<BeamsAlongRay> photon_beam_lookup;
    bool photon_beams_in_grid = false;
};

// Everything one iteration shares between the light pass and the eye pass; its large buffers
// are `storage`'s, cleared here.
class Iteration {
  public:
    Iteration(const BidirectionalConfig& config, const Scene& scene, const IterationKey& key,
              IterationStorage& storage)
        : config_(config),
          scene_(scene),
          key_(key),
          camera_(scene.camera()),
          light_trace_only_(config.mode == BidirectionalMode::LightTracing),
          ppm_(config.mode == BidirectionalMode::Ppm),
          vpl_(config.mode == BidirectionalMode::Vpl),
          ic_(config.mode == BidirectionalMode::Ic),
          ic_connections_(config.mode == BidirectionalMode::Bpt && config.ic_connections),
          many_lights_(vpl_ || ic_),
          use_vc_(config.mode == BidirectionalMode::Bpt ||
                  (config.mode == BidirectionalMode::Vcm && config.vertex_connections)),
          use_vm_(config.mode == BidirectionalMode::Ppm || config.mode == BidirectionalMode::Bpm ||
                  config.mode == BidirectionalMode::Vcm),
          max_length_(config.max_depth < 0 ? INT_MAX / 4 : config.max_depth),
          pixel_count_(uint64_t(camera_.width()) * uint64_t(camera_.height())),
          light_path_count_(config.light_path_count > 0 ? config.light_path_count : pixel_count_),
          radius_(merge_radius(config.radius_factor * scene.bounding_sphere().radius, config.alpha,
                               key.iteration)),
          // UPBP's volume estimators have their own schedule, reduced as their kernels'
          // dimensions ask (3 for photon points, 2 for query beams); without one, photon points
          // merge with the surfaces' radius.
          volume_radius_(
              config.volume_radius_factor > 0
                  ? merge_radius_in(config.volume_radius_factor * scene.bounding_sphere().radius,
                                    config.volume_alpha, key.iteration, 3)
                  : radius_),
          // Without a volume schedule of their own, query beams share the surfaces' radius
          // (a disc, like a surface merge: the same dimension).
          beam_radius_(
              config.volume_radius_factor > 0
                  ? merge_radius_in(config.volume_radius_factor * scene.bounding_sphere().radius,
                                    config.volume_alpha, key.iteration, 2)
                  : radius_),
          // The report's eta_VCM = pi r^2 N_light: the ratio of merging to connection
          // densities of the same path.
          eta_vcm_(kPi * radius_ * radius_ * double(light_path_count_)),
          // Photon points in media: the kernel is a ball, eta = 4/3 pi r^3 N_light.
          eta_vcm_volume_(4.0 / 3.0 * kPi * volume_radius_ * volume_radius_ * volume_radius_ *
                          double(light_path_count_)),
          // Query beams: the kernel is a disc around the camera segment, eta = pi r^2 N_light.
          eta_beam_(kPi * beam_radius_ * beam_radius_ * double(light_path_count_)),
          vm_normalization_(float(1.0 / eta_vcm_)),
          vm_normalization_volume_(float(1.0 / eta_vcm_volume_)),
          beam_normalization_(float(1.0 / eta_beam_)),
          merge_surfaces_(use_vm_ && config.surface_merging),
          merge_points_(use_vm_ && config.photon_points),
          query_beams_(config.mode == BidirectionalMode::Vcm && config.query_beams &&
                       scene.has_media()),
          photon_beams_(config.mode == BidirectionalMode::Vcm && config.photon_beams &&
                        scene.has_media()),
          // Photon beams: a 1-D kernel, r_i = r_1 i^(alpha - 1) (merge_radius_in at dimension
          // 1) on the volume schedule, else on the surfaces' factor and alpha.
          photon_beam_radius_(
              merge_radius_in((config.volume_radius_factor > 0 ? config.volume_radius_factor
                                                               : config.radius_factor) *
                                  scene.bounding_sphere().radius,
                              config.volume_radius_factor > 0 ? config.volume_alpha : config.alpha,
                              key.iteration, 1)),
          // The box kernel 1 / (2 r_1), each of the N_L light paths' beams one sample.
          photon_beam_normalization_(
              float(1.0 / (2.0 * photon_beam_radius_ * double(light_path_count_)))),
          mis_(config.mis_power,
               MisTechniques{.connections = use_vc_,
                             .surface_eta = merge_surfaces_ ? eta_vcm_ : 0.0,
                             .point_eta = merge_points_ ? eta_vcm_volume_ : 0.0,
                             .query_beam_eta = query_beams_ ? eta_beam_ : 0.0,
                             .photon_beam_eta = photon_beams_
                                                    ? config.photon_beam_eta * photon_beam_radius_ *
                                                          double(light_path_count_)
                                                    : 0.0,
                             .short_photon_beams = config.short_photon_beams},
               double(light_path_count_)),
          vpl_clamp2_(vpl_clamp_squared(config, scene, key.iteration)),
          vpl_scale_(float(1.0 / double(light_path_count_))),
          ic_light_path_count_(ic_connections_
                                   ? std::min<uint64_t>(config.ic_light_paths, light_path_count_)
                                   : light_path_count_),
          ic_connection_scale_(float(1.0 / double(ic_light_path_count_))),
          // bpt and vcm; not beside upbp's beams, whose weights have no J1 factors.
          joint_((config.mode == BidirectionalMode::Bpt || config.mode == BidirectionalMode::Vcm) &&
                 config.joint_connections && use_vc_ && !ic_connections_ && !query_beams_ &&
                 !photon_beams_ && scene.has_media() && scene.volume_lights().empty()),
          joint2_(joint_ && config.joint2_connections && config.mode == BidirectionalMode::Bpt),
          storage_(storage),
          light_vertices_(storage.light_vertices),
          path_ends_(storage.path_ends),
          light_rays_(storage.light_rays),
          ray_ends_(storage.ray_ends),
          joint2_vertices_(storage.joint2_vertices),
          surface_positions_(storage.surface_positions),
          medium_positions_(storage.medium_positions),
          surface_index_(storage.surface_index),
          medium_index_(storage.medium_index),
          surface_grid_(storage.surface_grid),
          medium_grid_(storage.medium_grid) {
        for (auto* v : {&surface_positions_, &medium_positions_}) v->clear();
        for (auto* v : {&path_ends_, &surface_index_, &medium_index_}) v->clear();
        light_rays_.clear();
        ray_ends_.clear();
        joint2_vertices_.clear();
        // Destroying the last iteration's vertices reads all of them (hundreds of MB): in
        // parallel over the blocks.
        tbb::parallel_for(size_t(0), light_vertices_.block_count(),
                          [&](size_t b) { light_vertices_.clear_block(b); });
        light_vertices_.clear();
    }

    // Traces the light paths in chunks, in parallel, and gathers each chunk in chunk order: its
    // vertices into light_vertices_ (and the merging grids' positions), its splats to
    // add_splats, on one thread at a time.
    void trace_light_paths(RenderStats& stats, const SplatSink& add_splats);
    // vpl with the importance-driven distribution: keeps each light vertex with its
    // probability P_k (dividing its throughput by P_k) and drops the others.
    void select_vpls(RenderStats& stats, VplSelection* inspection = nullptr);
    // ic, and bpt with ic connections: traces the records of the screen grid and builds their
    // tables over the light vertices (bpt: those of the first ic_light_path_count_ paths), the
    // lookup tree and the conservative fallback.
    void build_importance_cache(RenderStats& stats);
    bool uses_importance_caches() const { return ic_ || ic_connections_; }
    Rgb trace_eye_path(uint64_t pixel, RenderStats& stats, const LayerSink& sink) const;

    uint64_t light_path_count() const { return light_path_count_; }
    double photon_beam_radius() const { return photon_beam_radius_; }
    // The records' connections are clamped at 1 % of the scene radius at least, so that a VPL
    // lying on a record cannot take all the importance: this shapes P_k only, never the bias.
    float record_clamp2() const {
        const double radius = scene_.bounding_sphere().radius;
        return std::max(vpl_clamp2_, float(1e-4 * radius * radius));
    }

  private:
    // Solid-angle density, per unit pixel area, of the camera producing world direction `dir`
    // (the report's camera pdf with the image plane measured in pixels).
    float camera_pixel_pdf_w(const Vec3& dir) const {
        return camera_.direction_pdf_w(dir) * float(pixel_count_);
    }

    bool generate_light_sample(Rng& rng, SubpathState& state, Ray& ray) const;
    // A light subpath starting at a point of an emitting medium (docs/media.md, "Emitting media
    // as lights"), picked with probability pick_probability.
    bool generate_volume_light_sample(const VolumeEmitter& emitter, float pick_probability,
                                      Rng& rng, SubpathState& state, Ray& ray) const;
    // rays, joint2: where J2 keeps the path's light rays and the state of its stored vertices
    // (null without J2).
    void trace_light_path(uint64_t path_index, std::vector<LightVertex>& vertices,
                          std::vector<Splat>& splats, RenderStats& stats,
                          std::vector<LightRay>* rays = nullptr,
                          std::vector<Joint2Vertex>* joint2 = nullptr) const;
    // Traces the next segment of a subpath and, unless it left the scene, builds the vertex
    // it ends at and completes the MIS quantities' conversion (`arrive`).
    std::optional<SubpathVertex> next_vertex(const Ray& ray, TransportMode mode, Rng& rng,
                                             SubpathState& state, RenderStats& stats,
                                             SampledSegment& segment) const;
    bool sample_scattering(const SubpathVertex& v, const Vec3& wo, Rng& rng, SubpathState& state,
                           Ray& ray) const;
    Link link(const Ray& ray, const Medium* medium, bool start_in_medium, bool end_in_medium,
              Rng& rng, RenderStats& stats) const;
    Rgb visibility(const Link& link, const Ray& ray, RenderStats& stats) const;
    void connect_to_camera(const SubpathState& state, const SubpathVertex& v, const Vec3& wo,
                           Rng& rng, std::vector<Splat>& splats, RenderStats& stats) const;
    Rgb emission(const Light* light, const SubpathState& state, const Vec3& hit_point,
                 const Vec3& hit_normal, const Vec3& ray_direction) const;
    // The eye subpath's collision estimate of the emission at v, a vertex in an emitting medium
    // just reached (s = 0 with the medium as the light), MIS-weighted, without the throughput
    // before the segment (state.source_throughput holds it).
    Rgb medium_emission(const SubpathState& state, const Vertex& v) const;
    Rgb direct_illumination(const SubpathState& state, const SubpathVertex& v, const Vec3& wo,
                            Rng& rng, RenderStats& stats) const;
    // Next-event estimation's MIS-weighted contribution at v (without the eye throughput) for
    // the light sample dl, visibility included; joint: v was sampled by J1 at s = 1 toward the
    // light point (the weight is that technique's).
    Rgb direct_contribution(const MisQuantities& eye_mis, const SubpathVertex& v, const Vec3& wo,
                            const DirectLightSample& dl, Rng& rng, RenderStats& stats,
                            bool joint = false) const;
    // light_joint2: the light vertex's J2 state (joint2_of).
    Rgb connect_vertices(const LightVertex& light_vertex, const Joint2Vertex& light_joint2,
                         const SubpathVertex& v, const Vec3& wo, const MisQuantities& eye_mis,
                         Rng& rng, RenderStats& stats) const;
    // The J2 state of stored light vertex i (none without J2: the side array is empty then).
    const Joint2Vertex& joint2_of(uint32_t i) const {
        static const Joint2Vertex none;
        return joint2_ ? joint2_vertices_[i] : none;
    }
    // Joint connections for the eye segment about to be traced along `ray` from the eye
    // subpath's last vertex: each light vertex in [first, end) joined through a medium vertex
    // of the segment's first piece, sampled toward it; each passed to add(s, contribution).
    template <class Add>
    // [rays_first, rays_end): the light path's rays for J2 (light_rays_; empty: none).
    void joint_connections(const Ray& ray, const SubpathState& state, uint32_t first, uint32_t end,
                           uint32_t rays_first, uint32_t rays_end, Rng& rng, RenderStats& stats,
                           Add&& add) const;
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
    std::optional<ConnectionTerms> connection_terms(const LightVertex& light_vertex,
                                                    const Joint2Vertex& light_joint2,
                                                    const SubpathVertex& v, const Vec3& wo,
                                                    const MisQuantities& eye_mis, Rng& rng,
                                                    RenderStats& stats,
                                                    JointKind joint = JointKind::None) const;
    // J2: q = p_B2 / p_distance of the light-side vertex `x` of a junction, resampled on the
    // light ray from `light_point` (a light's point or a scattering vertex; x's density from there:
    // light_ray_pdf, 0 where J2 cannot resample it), the eye ray from `eye_origin` through
    // `eye_side`; 0 without J2.
    float light_joint2_ratio(const Vec3& light_point, const Vec3& x, float light_ray_pdf,
                             const Vec3& eye_origin, const Vec3& eye_side) const {
        if (!joint2_ || !(light_ray_pdf > 0)) return 0.0f;
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
    Rgb query_beams(const Ray& ray, const SubpathState& state, Rng& rng, RenderStats& stats) const;
    // The pieces of an eye segment along `ray`, walked as sample_segment does without sampling
    // a distance, up to the first surface that is not a null boundary: visit(medium, piece,
    // t_end, before, transmittance) for each piece in a medium, with the MIS densities and the
    // transmittance of the pieces before it. The walk of query_beams and photon_beams.
    template <typename Visit>
    void for_each_eye_medium_piece(const Ray& ray, const SubpathState& state, Rng& rng,
                                   RenderStats& stats, Visit&& visit) const;
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
    Rgb photon_beams(const Ray& ray, const SubpathState& state, Rng& rng, RenderStats& stats) const;
    // Both gathers over one walk of the eye segment's pieces (each normalised as the two
    // functions above normalise it): one closest hit and one transmittance per piece instead
    // of two. The sums are those of query_beams and photon_beams, in the same order.
    void both_beams(const Ray& ray, const SubpathState& state, Rng& rng, RenderStats& stats,
                    Rgb& query_sum, Rgb& photon_sum) const;
    // One piece's part of each gather (unnormalised), added to sum.
    void query_beams_in_piece(const Ray& ray, const SubpathState& state, const Medium* medium,
                              const Ray& piece, float t_end, const SegmentDensityBuilder& before,
                              const Rgb& transmittance, Rng& rng, Rgb& sum) const;
    void photon_beams_in_piece(const Ray& ray, const SubpathState& state, const Medium* medium,
                               const Ray& piece, float t_end, const SegmentDensityBuilder& before,
                               const Rgb& transmittance, Rng& rng, Rgb& sum) const;
    // B-B1D terms of a light vertex v (reached from wo) sampled from the camera side along
    // direction d with density pdf (without its distance density); 0 without the technique.
    float light_photon_beam_term(const Vertex& v, const Vec3& wo, const Vec3& d, float pdf) const;
    // Sets v's photon-beam quantities on arrival (a medium vertex reached by `seg`).
    void set_photon_beam_quantities(Vertex& v, const SampledSegment& seg, TransportMode mode) const;
    // Where photon beams live (docs/media.md, "Photon beams in grid media"): long beams in every
    // medium (ratio tracking estimates their transmittance), short ones where their weight is
    // known: the sampled distance's pass weight exactly (homogeneous media, grey grids), or in a
    // chromatic grid the sampling walk's own pass weight, replayed (replays_walk), on segments
    // of one piece. The weights use the same predicate, so a vertex no beam can reach has
    // M_B = 0 in every technique.
    bool beam_segment(const SegmentDensities& d) const {
        return !config_.short_photon_beams || d.short_beam_support;
    }
    // A short beam in `medium` carries the replayed walk's pass weight (a chromatic grid).
    bool replays_walk(const Medium* medium) const {
        return config_.short_photon_beams && !medium->is_homogeneous() &&
               !medium->pass_weight_is_one();
    }
    static std::optional<ConnectionGeometry> connection_geometry(const LightVertex& light_vertex,
                                                                 const Vertex& v, const Vec3& wo);
    // The VPL estimator's term for one light vertex at eye vertex v (without the eye and light
    // throughputs): f_v G f_light V / N_L, with G's distance clamped at sqrt(clamp2).
    Rgb vpl_connection(const LightVertex& light_vertex, const Vertex& v, const Vec3& wo,
                       float clamp2, Rng& rng, RenderStats& stats) const;
    // An importance record: the first non-delta vertex of a camera path through a random
    // image position, with the eye throughput that reaches it.
    struct Record {
        SubpathVertex vertex;
        Vec3 wo;
        Rgb throughput;
        int path_length;
        float distance;  // along the camera path (for the record's footprint)
        Vec3 camera_direction;
        MisQuantities mis;  // of the eye subpath ending at the record (ic connections' weights)
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
    // Importance caching at eye vertex v: light vertices drawn from the mixtures of v's
    // nearest records; each drawn vertex's `term` (its contribution without the eye
    // throughput), weighted by MIS between the four techniques and divided by its probability,
    // is passed to `add` with the number of light vertices s of its path.
    template <class Term, class Add>
    void draw_from_importance_caches(const Vertex& v, int eye_length, Rng& rng, Term&& term,
                                     Add&& add) const;
    // phi_k of every light vertex: the luminance of its contribution averaged over the
    // iteration's importance records (escaped records count as zero).
    std::vector<double> estimate_vpl_importance(RenderStats& stats) const;

    const BidirectionalConfig& config_;
    const Scene& scene_;
    IterationKey key_;
    const PerspectiveCamera& camera_;
    // many_lights_: vpl or ic, the two estimators over the iteration's VPLs (weight 1).
    // ic_connections_: bpt whose connections draw light vertices from importance caches.
    bool light_trace_only_, ppm_, vpl_, ic_, ic_connections_, many_lights_, use_vc_, use_vm_;
    int max_length_;
    uint64_t pixel_count_, light_path_count_;
    double radius_;
    double volume_radius_;  // photon points (P-P3D)
    double beam_radius_;    // query beams (P-B2D)
    double eta_vcm_, eta_vcm_volume_, eta_beam_;
    float vm_normalization_, vm_normalization_volume_, beam_normalization_;
    // Which merges are on (ppm, bpm, vcm: surfaces and photon points; upbp: as configured).
    bool merge_surfaces_, merge_points_, query_beams_, photon_beams_;
    double photon_beam_radius_;
    float photon_beam_normalization_;
    VcmMis mis_;
    float vpl_clamp2_;  // squared distance clamp of VPL connections (0: none)
    float vpl_scale_;   // 1 / N_L: each light path is one sample of the VPL estimator
    // The light paths whose vertices the importance caches cover (ic: all; bpt: a prefix) and
    // those vertices (a prefix of light_vertices_, set by build_importance_cache).
    uint64_t ic_light_path_count_;
    float ic_connection_scale_;  // 1 / ic_light_path_count_: the caches average over those paths
    bool joint_;                 // joint (J1) connections (bpt, vcm in a scene with media)
    bool joint2_;                // and J2 on the light path's rays (bpt only)
    size_t ic_vertex_count_ = 0;

    IterationStorage& storage_;
    BlockVector<LightVertex>& light_vertices_;
    std::vector<uint32_t>& path_ends_;            // light_vertices_ of path p: [ends[p-1], ends[p])
    std::vector<LightRay>& light_rays_;           // with J2 (else empty)
    std::vector<uint32_t>& ray_ends_;             // light_rays_ of path p end here (with J2)
    BlockVector<Joint2Vertex>& joint2_vertices_;  // of light vertex i, with J2 (else empty)
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
    // eye vertices of their own kind); *_index_ maps a grid point to its light vertex.
    std::vector<Vec3>&surface_positions_, &medium_positions_;
    std::vector<uint32_t>&surface_index_, &medium_index_;
    HashGrid &surface_grid_, &medium_grid_;
};

}  // namespace vcm_detail
}  // namespace render
