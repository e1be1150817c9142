#include "core/integrators/vertex_cm.h"

#include <tbb/blocked_range.h>
#include <tbb/combinable.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_pipeline.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <climits>
#include <cmath>
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
namespace {

// Light paths draw from streams disjoint from the pixels' (stream = pixel index).
constexpr uint64_t kLightStreamBase = uint64_t(1) << 62;
// Importance records (camera points of the importance-driven VPL distribution) and the
// acceptance draws of VPL candidates use streams of their own.
constexpr uint64_t kRecordStreamBase = kLightStreamBase + (uint64_t(1) << 60);
constexpr uint64_t kAcceptStreamBase = kLightStreamBase + (uint64_t(2) << 60);
constexpr uint64_t kImportanceStreamBase = kLightStreamBase + (uint64_t(3) << 60);
// Importance caching: the records of the screen grid, and their tables' shadow rays.
constexpr uint64_t kIcRecordStreamBase = kLightStreamBase + (uint64_t(4) << 60);
constexpr uint64_t kIcTableStreamBase = kLightStreamBase + (uint64_t(5) << 60);
// Photon beams in grid media: the ratio-tracking transmittance of a long beam's earlier pieces,
// one stream per (light path, segment), so the light path's own numbers are not consumed.
constexpr uint64_t kPhotonBeamStreamBase = kLightStreamBase + (uint64_t(9) << 60);
// bpt with ic connections: records at the first non-delta vertices of each record path (eye
// vertices t = 2, 3, 4), so that eye vertices past the first find records that saw what they see.
constexpr int kIcConnectionRecordsPerPath = 3;
// Importance caching keeps its tables (four doubles per record and VPL) below this size; a
// denser record grid is thinned to fit (docs/algorithms.md).
constexpr double kIcTableBytes = 512.0 * 1024 * 1024;
// Light paths are traced in fixed chunks whose vertices are kept, and whose splats are added,
// in chunk order, so the image does not depend on the number of threads.
constexpr uint64_t kLightPathChunk = 256;
// Chunks traced but not yet gathered, per thread: enough that no thread waits for a slow chunk
// to be gathered, few enough that their buffers stay small next to the light vertices.
constexpr int kLightChunksInFlightPerThread = 4;

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
    // Joint (J2) connections on the light's emission ray: the position before origin_previous,
    // the light-ray distance densities of the origin vertex and of its predecessor (Joint2Vertex);
    // on eye subpaths the J1 share of the connection term the last scatter added to dVC (vcm_mis.h,
    // carried_eye_joint2_term), and, after arriving at a light, the J2 term the emission weight
    // adds to dVC (there the vertex the segment left is the light-side vertex of a J2 junction).
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
    Vec3 p;
    Vec3 n;  // geometric normal; zero in a medium
    const Shape* shape = nullptr;
    const Medium* medium = nullptr;  // the medium the path arrived in
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

// Joint (J2) connections' state of a subpath vertex, which resample the first light vertex on
// the light's emission ray (docs/media.md): the position `previous` was reached from; this
// vertex's distance density from `previous` where J2 can resample it there (a medium vertex of
// a homogeneous medium reached in one piece from a finite light's point, on either subpath: 0
// elsewhere), and the same of `previous`. Stored light vertices keep it in a side array indexed
// like them (IterationStorage::joint2_vertices), filled only with J2, so that the stored vertex
// does not pay for it when J2 is off.
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

// A stored light-subpath vertex with a non-delta BSDF or in a medium.
struct LightVertex {
    [[no_unique_address]] Vertex vertex;  // the next member fills its tail padding
    Vec3 wo;                              // toward the previous vertex of the light subpath
    Rgb throughput;
    int path_length;
    MisQuantities mis;
    bool finite_light = true;  // the subpath starts at a point (J1 at s = 1 needs one)
};
static_assert(sizeof(Joint2Vertex) <= kJoint2VertexBytesBound,
              "Joint2Vertex grew: raise kJoint2VertexBytesBound (the memory estimate uses it)");
static_assert(sizeof(LightVertex) <= kLightVertexBytesBound,
              "LightVertex grew: raise kLightVertexBytesBound (the memory estimate uses it)");

// Which technique produced a connection: the plain one, J1 (the eye vertex sampled toward the
// light vertex) or J2 (the light vertex resampled on the emission ray as well).
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
float joint_pdf_l(const Vec3& from, const Vec3& x, const Vec3& toward) {
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
    // A short beam in a chromatic grid (Iteration::replays_walk): the random state its sampling
    // walk started with and that walk's t_max, replayed to the closest approach for its weight.
    float replay_t_max = 0;
    Rng replay{StreamKey{}};
};
static_assert(sizeof(PhotonBeam) <= kPhotonBeamBytesBound,
              "PhotonBeam grew: raise kPhotonBeamBytesBound (the memory estimate uses it)");

// The squared distance clamp of VPL connections in (1-based, global) iteration i; 0 unclamped.
double vpl_clamp_squared(const BidirectionalConfig& config, const Scene& scene,
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

}  // namespace

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
    tbb::enumerable_thread_specific<std::vector<PhotonBeam>> photon_beam_staging;
    std::vector<PhotonBeam> photon_beams;
    std::vector<BeamLine> photon_beam_lines;
    // Their lookup: a uniform grid (measured 3-4x faster per query than the Embree BVH,
    // docs/media.md), or the BVH in an iteration where a beam leaves the scene's box (a beam
    // escaping through an unbounded medium: the grid would have to span it).
    UniformBeamGrid photon_beam_grid;
    std::unique_ptr<BeamsAlongRay> photon_beam_lookup;
    bool photon_beams_in_grid = false;
};

namespace {

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
    // emission ray from the light point `light_point` (x's distance density from there:
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
    bool joint2_;                // and J2 on the emission ray (bpt only)
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

// --- segments and links -----------------------------------------------------------------------

std::optional<SubpathVertex> Iteration::next_vertex(const Ray& ray, TransportMode mode, Rng& rng,
                                                    SubpathState& state, RenderStats& stats,
                                                    SampledSegment& seg) const {
    if (!state.medium && !scene_.has_media()) {
        // Surface-only scenes: one closest hit, every distance density 1 (as sample_segment
        // would return, without its bookkeeping).
        ++stats.rays;
        if (!scene_.intersect(ray, seg.si)) return std::nullopt;
        seg.end = SegmentEnd::Surface;
        seg.position = seg.si.p;
        seg.distance = seg.si.t;
    } else {
        seg = sample_segment(scene_, ray, state.medium, state.in_medium, rng, stats);
        // The eye collects emission at vertices of emitting media even where nothing scatters
        // (albedo 0); trace_eye_path ends the path after it.
        const bool collects_emission = mode == TransportMode::Radiance &&
                                       seg.end == SegmentEnd::Medium && seg.medium->is_emissive() &&
                                       !scene_.volume_lights().empty();
        if (collects_emission) state.source_throughput = state.throughput * seg.source_weight;
        state.throughput *= seg.weight;
        if (seg.end == SegmentEnd::Escaped || (state.throughput.is_black() && !collects_emission))
            return std::nullopt;
    }
    SubpathVertex v;
    v.p = seg.position;
    v.medium = seg.medium;
    v.previous = state.origin;
    v.joint2.previous2 = state.origin_previous;
    v.joint2.previous_light_ray_pdf = state.origin_light_ray_pdf;
    const Vec3 wo = -ray.direction;
    if (seg.end == SegmentEnd::Medium) {
        v.phase = &seg.medium->phase();
        if (seg.one_piece) v.joint_distance_pdf = seg.densities.toward_end;
        // J2's light-side vertex: a light subpath's medium vertex reached in one piece from a
        // scattering vertex or a finite light's point (record_light_ray keeps that ray).
        if (joint2_ && mode == TransportMode::Importance && seg.one_piece &&
            joint_light_side(state.path_length, state.is_finite_light) &&
            seg.medium->is_homogeneous())
            v.joint2.light_ray_pdf = seg.densities.toward_end;
        if (mode == TransportMode::Radiance)
            v.query_beam = mis_.query_beam_factor(seg.densities.toward_end);
        if (photon_beams_) set_photon_beam_quantities(v, seg, mode);
    } else {
        v.n = seg.si.geometric_normal;
        v.shape = seg.si.shape;
        v.bsdf.emplace(*seg.si.bsdf, seg.si.shading, seg.si.geometric_normal, mode);
    }
    const float cos_in = v.cos(wo);
    if (!(cos_in > 0)) return std::nullopt;
    // For infinite lights the first segment has no distance term.
    mis_.arrive(state.mis, seg.distance * seg.distance,
                state.path_length > 1 || state.is_finite_light, cos_in, seg.densities.toward_end,
                seg.densities.toward_start);
    // Light subpaths: the J1 technique of the junction whose eye-side vertex is the one this
    // segment left (a medium vertex whose light-side neighbour scatters, or is a finite light's
    // point: J1 at s = 1), sampled from here.
    if (joint_ && mode == TransportMode::Importance && state.carried_connection > 0 &&
        state.origin_in_medium && joint_light_side(state.path_length - 1, state.is_finite_light) &&
        seg.one_piece)
        mis_.add_joint_term(
            state.mis, state.carried_connection,
            joint_pdf_l(v.p, state.origin, state.origin_previous), cos_in, seg.densities.toward_end,
            light_joint2_ratio(state.origin_previous2, state.origin_previous,
                               state.origin_previous_light_ray_pdf, v.p, state.origin));
    // Eye subpaths: the vertex the segment left is the light-side vertex of a J2 junction whose
    // light ray starts here (at a light's point should the path end here, or at a scattering
    // vertex of the light subpath); every technique that has this vertex on the light side
    // counts it (vcm_mis.h, add_eye_joint2_term).
    if (joint2_ && mode == TransportMode::Radiance && state.carried_eye_joint2 > 0 &&
        seg.one_piece && state.origin_in_medium && state.medium && state.medium->is_homogeneous())
        mis_.add_eye_joint2_term(state.mis, state.carried_eye_joint2,
                                 joint2_pdf_l(scene_.bounding_sphere(), v.p, state.origin,
                                              state.origin_previous2, state.origin_previous),
                                 cos_in, seg.densities.toward_end);
    // Light subpaths: the P-B2D term of the vertex this segment left (the segment from here is
    // the query that covers it).
    if (mode == TransportMode::Importance)
        mis_.add_query_beam_term(state.mis, state.carried_query_beam, cos_in,
                                 seg.densities.toward_end);
    // Photon beams: the B-B1D term of the vertex this segment left (on eye subpaths, this
    // segment is the photon beam that reaches it).
    // Light subpaths: whether the vertex's own arrival can carry a beam is in its carried term
    // already (this segment is the long query, which needs no support).
    const bool eye = mode == TransportMode::Radiance;
    mis_.add_photon_beam_term(state.mis, state.carried_photon_beam, cos_in,
                              seg.densities.toward_end, seg.densities.toward_start, eye,
                              !eye || beam_segment(seg.densities));
    return v;
}

void Iteration::set_photon_beam_quantities(Vertex& v, const SampledSegment& seg,
                                           TransportMode mode) const {
    v.arrival_distance = seg.densities.toward_end;
    v.sigma_t = seg.medium->sigma_t(v.p).average();
    if (!(v.sigma_t > 0)) return;
    if (mode == TransportMode::Radiance)
        v.photon_beam = mis_.photon_beam_eye_factor(v.arrival_distance, v.sigma_t);
    else if (beam_segment(seg.densities))
        v.photon_beam = mis_.photon_beam_light_factor(v.arrival_distance, v.sigma_t);
}

float Iteration::light_photon_beam_term(const Vertex& v, const Vec3& wo, const Vec3& d,
                                        float pdf) const {
    if (!(v.photon_beam > 0)) return 0.0f;
    return mis_.photon_beam_light_term(length(cross(wo, d)), pdf, v.arrival_distance, v.sigma_t);
}

Link Iteration::link(const Ray& ray, const Medium* medium, bool start_in_medium, bool end_in_medium,
                     Rng& rng, RenderStats& stats) const {
    if (!scene_.has_media()) return Link{};
    const SegmentConnection c =
        connect_segment(scene_, ray, medium, start_in_medium, end_in_medium, rng, stats);
    return Link{c.densities, c.transmittance, true, c.one_piece};
}

Rgb Iteration::visibility(const Link& l, const Ray& ray, RenderStats& stats) const {
    if (l.traced) return l.transmittance;
    ++stats.rays;
    return scene_.occluded(ray) ? Rgb(0.0f) : Rgb(1.0f);
}

// --- light subpaths ---------------------------------------------------------------------------

bool Iteration::generate_light_sample(Rng& rng, SubpathState& state, Ray& ray) const {
    float pick_probability = 0;
    const Light* light = scene_.sample_emitter(rng.next_1d(), &pick_probability);
    if (light && light->as_volume())
        return generate_volume_light_sample(*light->as_volume(), pick_probability, rng, state, ray);
    Vec2 u_position = rng.next_2d(), u_direction = rng.next_2d();
    LightEmitSample e;
    if (!light || !(pick_probability > 0) || !light->emit(u_position, u_direction, e)) return false;
    const float emission_pdf_w = e.pdf_emission_w * pick_probability;
    const float direct_pdf_a = e.pdf_direct_a * pick_probability;
    if (!(emission_pdf_w > 0)) return false;

    state.throughput = e.energy / emission_pdf_w;
    state.initial_luminance = std::max(state.throughput.max(), 1e-30f);
    state.path_length = 1;
    state.is_finite_light = light->is_finite();
    state.medium = light->is_finite() ? light->medium : nullptr;
    state.in_medium = false;
    // Infinite lights have no cosine at the (virtual) emission point; a delta light cannot be
    // hit, so no technique ends on it by chance (eqs. 31-33).
    state.mis = mis_.start_light(direct_pdf_a, emission_pdf_w,
                                 light->is_finite() ? e.cos_at_light : 1.0f, light->is_delta());
    state.origin = e.origin;
    // Offsetting along the direction keeps the ray off the emitting surface.
    ray = light->is_finite() ? scene_.spawn_ray(e.origin, e.direction, e.direction)
                             : Ray(e.origin, e.direction);
    return state.throughput.is_finite();
}

bool Iteration::generate_volume_light_sample(const VolumeEmitter& emitter, float pick_probability,
                                             Rng& rng, SubpathState& state, Ray& ray) const {
    const VolumeLightSample y = sample_volume_light_start(emitter, pick_probability, rng);
    if (!y.valid) return false;
    state.throughput = y.source / y.emission_pdf_w;
    state.initial_luminance = std::max(state.throughput.max(), 1e-30f);
    state.path_length = 1;
    state.is_finite_light = true;
    // y_0 is a medium vertex: the first segment starts inside the medium, without an offset.
    state.medium = emitter.medium;
    state.in_medium = true;
    // Eqs. (31)-(33) with cos = 1 and the volume density (docs/media.md).
    state.mis = start_volume_light_mis(mis_, y.direct_pdf_a);
    state.origin = y.p;
    ray = Ray(y.p, y.direction);
    return state.throughput.is_finite();
}

void Iteration::trace_light_path(uint64_t path_index, std::vector<LightVertex>& vertices,
                                 std::vector<Splat>& splats, RenderStats& stats,
                                 std::vector<LightRay>* rays,
                                 std::vector<Joint2Vertex>* joint2) const {
    Rng rng(StreamKey{key_.seed, key_.frame, key_.iteration, kLightStreamBase + path_index});
    SubpathState state;
    Ray ray;
    if (!generate_light_sample(rng, state, ray)) return;
    // J2 joins a ray's resampled vertex (after path_length segments) to an eye vertex: rays whose
    // paths would exceed max_depth are not kept.
    if (rays && state.is_finite_light && 3 <= max_length_)
        record_light_ray(ray, state, 1, *rays, stats);

    uint32_t beam_piece = 0;
    for (;; ++state.path_length) {
        SampledSegment seg;
        // Photon beams need the subpath as it was before the segment.
        std::optional<SubpathState> before;
        if (photon_beams_) before = state;
        std::optional<SubpathVertex> v =
            next_vertex(ray, TransportMode::Importance, rng, state, stats, seg);
        if (before) emit_photon_beams(ray, *before, seg, path_index, beam_piece, rng, stats);
        if (!v) break;
        const Vec3 wo = -ray.direction;
        // Delta BSDFs can neither be connected to nor merged at (the report's specular vertices).
        if (v->has_non_delta()) {
            if (use_vc_ || use_vm_ || many_lights_) {
                vertices.push_back(LightVertex{*v, wo, state.throughput, state.path_length,
                                               state.mis, state.is_finite_light});
                if (joint2) joint2->push_back(v->joint2);
            }
            if ((use_vc_ || light_trace_only_) && state.path_length + 1 <= max_length_)
                connect_to_camera(state, *v, wo, rng, splats, stats);
        }
        // Extending needs one more segment plus at least the segment to the eye.
        if (state.path_length + 2 > max_length_) break;
        if (!sample_scattering(*v, wo, rng, state, ray)) break;
        if (rays && state.path_length + 3 <= max_length_)
            record_light_ray(ray, state, state.path_length + 1, *rays, stats);
    }
}

void Iteration::record_light_ray(const Ray& ray, const SubpathState& state, int path_length,
                                 std::vector<LightRay>& rays, RenderStats& stats) const {
    if (!state.medium || !state.medium->is_homogeneous()) return;
    // The ray's first piece (one closest hit per light ray).
    ++stats.rays;
    LightRay r;
    r.origin = state.origin;
    r.direction = ray.direction;
    r.throughput = state.throughput;
    r.mis = state.mis;
    r.medium = state.medium;
    r.piece_end = dot(ray.origin - state.origin, ray.direction) + scene_.closest_hit_distance(ray);
    r.origin_previous = state.origin_previous;
    r.origin_previous2 = state.origin_previous2;
    r.origin_light_ray_pdf = state.origin_light_ray_pdf;
    r.origin_previous_light_ray_pdf = state.origin_previous_light_ray_pdf;
    r.carried_connection = state.carried_connection;
    r.path_length = path_length;
    r.origin_in_medium = state.origin_in_medium;
    r.finite_light = state.is_finite_light;
    rays.push_back(r);
}

void Iteration::trace_light_paths(RenderStats& stats, const SplatSink& add_splats) {
    const uint64_t chunks = (light_path_count_ + kLightPathChunk - 1) / kLightPathChunk;
    // Chunk buffers: cleared, their capacity kept from the last iteration.
    std::vector<LightChunk*>& free_chunks = storage_.free_light_chunks;
    free_chunks.clear();
    for (const std::unique_ptr<LightChunk>& c : storage_.light_chunks)
        free_chunks.push_back(c.get());
    auto take_chunk = [&] {
        std::lock_guard lock(storage_.light_chunks_mutex);
        if (free_chunks.empty()) {
            storage_.light_chunks.push_back(std::make_unique<LightChunk>());
            return storage_.light_chunks.back().get();
        }
        LightChunk* chunk = free_chunks.back();
        free_chunks.pop_back();
        return chunk;
    };
    auto give_back = [&](LightChunk* chunk) {
        std::lock_guard lock(storage_.light_chunks_mutex);
        free_chunks.push_back(chunk);
    };

    path_ends_.reserve(light_path_count_);
    uint64_t next_chunk = 0;
    auto next = [&](tbb::flow_control& control) -> LightChunk* {
        if (next_chunk == chunks) {
            control.stop();
            return nullptr;
        }
        LightChunk* chunk = take_chunk();
        chunk->index = next_chunk++;
        return chunk;
    };
    auto trace = [&](LightChunk* chunk) {
        chunk->vertices.clear();
        chunk->path_sizes.clear();
        chunk->light_rays.clear();
        chunk->ray_counts.clear();
        chunk->joint2_vertices.clear();
        chunk->splats.clear();
        chunk->stats = RenderStats{};
        const uint64_t first = chunk->index * kLightPathChunk;
        const uint64_t last = std::min(first + kLightPathChunk, light_path_count_);
        for (uint64_t p = first; p < last; ++p) {
            const size_t before = chunk->vertices.size(), rays_before = chunk->light_rays.size();
            trace_light_path(p, chunk->vertices, chunk->splats, chunk->stats,
                             joint2_ ? &chunk->light_rays : nullptr,
                             joint2_ ? &chunk->joint2_vertices : nullptr);
            chunk->path_sizes.push_back(uint32_t(chunk->vertices.size() - before));
            if (joint2_)
                chunk->ray_counts.push_back(uint32_t(chunk->light_rays.size() - rays_before));
        }
        return chunk;
    };
    uint32_t end = 0;
    auto gather = [&](LightChunk* chunk) {
        for (uint32_t size : chunk->path_sizes) path_ends_.push_back(end += size);
        uint32_t ray_end = uint32_t(light_rays_.size());
        for (uint32_t count : chunk->ray_counts) ray_ends_.push_back(ray_end += count);
        light_rays_.insert(light_rays_.end(), chunk->light_rays.begin(), chunk->light_rays.end());
        for (const Joint2Vertex& j : chunk->joint2_vertices) joint2_vertices_.push_back(j);
        for (LightVertex& v : chunk->vertices) {
            if (use_vm_) {
                const bool medium = v.vertex.in_medium();
                (medium ? medium_positions_ : surface_positions_).push_back(v.vertex.p);
                (medium ? medium_index_ : surface_index_)
                    .push_back(uint32_t(light_vertices_.size()));
            }
            light_vertices_.push_back(std::move(v));
        }
        add_splats(chunk->splats);
        stats += chunk->stats;
        give_back(chunk);
    };
    // Gathering runs on one thread at a time, in chunk order (deterministic whatever the thread
    // count), while the other threads go on tracing later chunks.
    const size_t in_flight =
        size_t(kLightChunksInFlightPerThread) * size_t(tbb::this_task_arena::max_concurrency());
    tbb::parallel_pipeline(
        in_flight,
        tbb::make_filter<void, LightChunk*>(tbb::filter_mode::serial_in_order, next) &
            tbb::make_filter<LightChunk*, LightChunk*>(tbb::filter_mode::parallel, trace) &
            tbb::make_filter<LightChunk*, void>(tbb::filter_mode::serial_in_order, gather));

    if (use_vm_) {
        // Each grid point carries its light vertex's index: a merge goes from the point straight
        // to the vertex (the index arrays are increasing, so the visiting order is unchanged).
        surface_grid_.build(surface_positions_, radius_, surface_index_);
        medium_grid_.build(medium_positions_, volume_radius_, medium_index_);
    }
    if (query_beams_) {
        if (!storage_.beam_lookup) storage_.beam_lookup = std::make_unique<PointsAlongRay>();
        storage_.beam_lookup->build(medium_positions_, float(beam_radius_));
    }
    if (photon_beams_) build_photon_beams();
}

bool Iteration::sample_scattering(const SubpathVertex& v, const Vec3& wo, Rng& rng,
                                  SubpathState& state, Ray& ray) const {
    const float u_lobe = rng.next_1d();
    const Vec2 u = rng.next_2d();
    std::optional<BsdfSample> bs = v.sample(wo, u_lobe, u);
    if (!bs || bs->weight.is_black()) return false;
    const float cos_out = v.cos(bs->wi);
    if (!(cos_out > 0)) return false;

    if (!bs->delta && !(bs->pdf_w.forward > 0)) return false;
    if (joint_)
        state.carried_connection =
            mis_.carried_connection_term(state.mis, cos_out, bs->pdf_w.forward, bs->delta);
    // Eye subpaths (J2 on the emission ray): the J1 share of the term this scatter adds, for
    // the emission weight should the next vertex be a light (light subpaths ignore it).
    state.carried_eye_joint2 =
        joint2_ && v.in_medium() && v.medium->is_homogeneous()
            ? mis_.carried_eye_joint2_term(state.mis, v.camera_joint_ratio, cos_out,
                                           bs->pdf_w.forward, bs->delta)
            : 0.0f;
    state.carried_query_beam =
        v.in_medium() ? mis_.carried_query_beam_term(cos_out, bs->pdf_w.forward, bs->delta) : 0.0f;
    if (photon_beams_)
        state.carried_photon_beam =
            v.in_medium() ? mis_.carried_photon_beam_term(cos_out, bs->pdf_w.forward, bs->delta,
                                                          length(cross(wo, bs->wi)), v.photon_beam)
                          : 0.0f;
    // Eqs. (34)-(36); Russian roulette below is deliberately not part of the densities.
    mis_.scatter(state.mis, cos_out, bs->pdf_w.forward, bs->pdf_w.reverse, bs->delta, v.in_medium(),
                 v.query_beam);
    state.origin_previous2 = state.origin_previous;
    state.origin_previous_light_ray_pdf = state.origin_light_ray_pdf;
    state.origin_light_ray_pdf = v.joint2.light_ray_pdf;
    state.origin = v.p;
    state.origin_previous = v.previous;
    state.origin_joint_pdf = v.joint_distance_pdf;
    state.origin_in_medium = v.in_medium();
    state.specular_path = state.specular_path && bs->delta;
    state.throughput *= bs->weight;

    if (state.path_length >= config_.rr_depth) {
        const float q = std::min(0.95f, state.throughput.max() / state.initial_luminance);
        if (!(q > 0) || rng.next_1d() >= q) return false;
        state.throughput *= 1.0f / q;
    }
    state.medium = v.medium_toward(wo, bs->wi);
    state.in_medium = v.in_medium();
    ray = v.in_medium() ? Ray(v.p, bs->wi) : scene_.spawn_ray(v.p, v.n, bs->wi);
    return true;
}

void Iteration::connect_to_camera(const SubpathState& state, const SubpathVertex& v, const Vec3& wo,
                                  Rng& rng, std::vector<Splat>& splats, RenderStats& stats) const {
    std::optional<Vec2> raster = camera_.raster_position(v.p);
    if (!raster) return;
    const Vec3 to_camera = camera_.position() - v.p;
    const float dist2 = length_squared(to_camera);
    if (!(dist2 > 0)) return;
    const Vec3 d = to_camera / std::sqrt(dist2);
    const auto [f, pdf_w] = v.evaluate(wo, d);
    if (f.is_black()) return;
    const Ray ray = scene_.spawn_ray_to(v.p, v.n, camera_.position(), Vec3());
    const Link l = link(ray, v.medium_toward(wo, d), v.in_medium(), false, rng, stats);
    if (l.traced && l.transmittance.is_black()) return;
    const float camera_pdf_w = camera_pixel_pdf_w(-d);
    // The camera's density of this vertex (eq. 46), through the media on the way.
    const float camera_pdf_a = camera_pdf_w * v.cos(d) * l.densities.toward_start / dist2;
    // J1 of the junction whose eye-side vertex is this one, sampled along the camera ray.
    float light_joint_ratio = 0;
    if (joint_ && v.in_medium() && joint_light_side(state.path_length, state.is_finite_light) &&
        l.one_piece && l.densities.toward_start > 0)
        light_joint_ratio =
            joint_pdf_l(camera_.position(), v.p, v.previous) / l.densities.toward_start;
    const float camera_light_joint2 =
        light_joint_ratio > 0
            ? light_joint2_ratio(v.joint2.previous2, v.previous, v.joint2.previous_light_ray_pdf,
                                 camera_.position(), v.p)
            : 0.0f;
    // P-B2D at this vertex with the camera ray as the query.
    const float light_query_beam =
        v.in_medium()
            ? mis_.query_beam_term(camera_pdf_w * v.cos(d) / dist2 / float(light_path_count_))
            : 0.0f;
    // B-B1D at this vertex, the camera ray as the query.
    const float light_photon_beam = light_photon_beam_term(
        v, wo, d, camera_pdf_w * v.cos(d) / dist2 / float(light_path_count_));
    const float weight =
        light_trace_only_
            ? 1.0f
            : mis_.weight_camera(state.mis, {.camera_pdf_a = camera_pdf_a,
                                             .light_reverse_w = pdf_w.reverse,
                                             .light_medium = v.in_medium(),
                                             .light_query_beam = light_query_beam,
                                             .light_joint_ratio = light_joint_ratio,
                                             .light_joint2_ratio = camera_light_joint2,
                                             .light_photon_beam = light_photon_beam});
    const Rgb contribution =
        state.throughput * f *
        (weight * camera_pdf_w * v.shading_cos(d) / (dist2 * float(light_path_count_)));
    if (contribution.is_black()) return;
    const Rgb tr = visibility(l, ray, stats);
    if (tr.is_black()) return;
    const uint32_t x = std::min(uint32_t(raster->x), uint32_t(camera_.width() - 1));
    const uint32_t y = std::min(uint32_t(raster->y), uint32_t(camera_.height() - 1));
    splats.push_back(
        Splat{y * uint32_t(camera_.width()) + x, contribution * tr, state.path_length + 1});
}

// --- eye subpaths -----------------------------------------------------------------------------

Rgb Iteration::emission(const Light* light, const SubpathState& state, const Vec3& hit_point,
                        const Vec3& hit_normal, const Vec3& ray_direction) const {
    const LightRadiance le = light->radiance(hit_point, hit_normal, ray_direction);
    if (le.radiance.is_black()) return Rgb(0.0f);
    // Directly visible emitters: no other technique samples paths of length 1.
    if (state.path_length == 1) return le.radiance;
    // Without connections (LT, PPM, BPM), emission found by the eye counts only along purely
    // specular chains, which nothing else can sample; every other path is left to the light
    // subpaths (connections to the camera, or merging).
    if (!use_vc_) return state.specular_path ? le.radiance : Rgb(0.0f);
    const float pick_probability = scene_.emitter_pick_probability(light);
    // J1 at s = 1 of the eye vertex before the hit point (sampled toward it): it multiplies
    // next-event estimation's term.
    float joint_ratio = 0;
    if (joint_ && light->is_finite() && state.origin_joint_pdf > 0)
        joint_ratio =
            joint_pdf_l(state.origin_previous, state.origin, hit_point) / state.origin_joint_pdf;
    // (J2 on the emission ray, the vertex before the hit point resampled on it, is in dVC:
    // next_vertex added it on arriving here.)
    return le.radiance * mis_.weight_emission(state.mis, le.pdf_direct_a * pick_probability,
                                              le.pdf_emission_w * pick_probability, joint_ratio);
}

Rgb Iteration::medium_emission(const SubpathState& state, const Vertex& v) const {
    const Light* light = scene_.volume_light_of(v.medium);
    if (!light) return Rgb(0.0f);
    const VolumeEmitter& emitter = *light->as_volume();
    const Rgb le = state.source_throughput * emitter.source_in_medium(v.p);
    if (le.is_black()) return Rgb(0.0f);
    // As emission(): directly visible emission has no other technique, and without
    // connections only purely specular chains count (light subpaths sample the rest).
    if (state.path_length == 1) return le;
    if (!use_vc_) return state.specular_path ? le : Rgb(0.0f);
    // Next-event estimation's density of this point (volume measure) and the light subpath's.
    const float direct_pdf_a = scene_.emitter_pick_probability(light) * emitter.pdf_volume(v.p);
    return le * volume_emission_weight(mis_, state.mis, direct_pdf_a);
}

Rgb Iteration::direct_illumination(const SubpathState& state, const SubpathVertex& v,
                                   const Vec3& wo, Rng& rng, RenderStats& stats) const {
    DirectLightSample dl;
    if (!sample_direct_emitter(scene_, v.p, rng, dl)) return Rgb(0.0f);
    return direct_contribution(state.mis, v, wo, dl, rng, stats);
}

Rgb Iteration::direct_contribution(const MisQuantities& eye_mis, const SubpathVertex& v,
                                   const Vec3& wo, const DirectLightSample& dl, Rng& rng,
                                   RenderStats& stats, bool joint) const {
    const LightIlluminateSample& ls = dl.ls;
    const auto [f, pdf_w] = v.evaluate(wo, ls.wi);
    if (f.is_black()) return Rgb(0.0f);
    const Ray ray = dl.shadow_ray(scene_, v.p, v.n);
    // A volume light's point is a medium vertex: the eye would reach it by a scattering event.
    const Link l = link(ray, v.medium_toward(wo, ls.wi), v.in_medium(),
                        dl.light->as_volume() != nullptr, rng, stats);
    if (l.traced && l.transmittance.is_black()) return Rgb(0.0f);
    // B-B1D at v, the light's emission segment toward v as the photon beam: the emission's
    // density of v (relative to the light's direct density, as eq. 45 forms it) with and
    // without the distance density.
    float eye_photon_beam = 0;
    if (v.photon_beam > 0 && ls.cos_at_light > 0) {
        const float emission =
            ls.pdf_emission_w * v.cos(ls.wi) / (ls.pdf_direct_w * ls.cos_at_light);
        eye_photon_beam = mis_.photon_beam_eye_term(length(cross(wo, ls.wi)), v.arrival_distance,
                                                    v.sigma_t, emission * l.densities.toward_start,
                                                    emission, beam_segment(l.densities));
    }
    // J1 at s = 1 (v sampled from its predecessor toward the light point).
    float joint_ratio = 0;
    if (joint_ && v.joint_distance_pdf > 0 && std::isfinite(ls.distance))
        joint_ratio =
            joint_pdf_l(v.previous, v.p, v.p + ls.wi * ls.distance) / v.joint_distance_pdf;
    // J2 of the junction toward the camera, v resampled on the light's emission ray toward it.
    float eye_joint2 = 0;
    if (joint2_ && v.camera_joint_ratio > 0 && v.in_medium() && v.medium->is_homogeneous() &&
        std::isfinite(ls.distance) && l.one_piece && l.densities.toward_start > 0)
        eye_joint2 =
            mis_.eye_joint2_term(eye_mis, v.camera_joint_ratio,
                                 joint2_pdf_l(scene_.bounding_sphere(), v.p + ls.wi * ls.distance,
                                              v.p, v.joint2.previous2, v.previous) /
                                     l.densities.toward_start);
    // Eqs. (44) and (45); VPL rendering has no other technique for these paths.
    const DirectTechnique technique{.bsdf_forward_w = pdf_w.forward,
                                    .bsdf_reverse_w = pdf_w.reverse,
                                    .light_pdf_w = dl.pdf_w(),
                                    .emission_pdf_w = ls.pdf_emission_w,
                                    .direct_pdf_w = ls.pdf_direct_w,
                                    .cos_here = v.cos(ls.wi),
                                    .cos_light = ls.cos_at_light,
                                    .delta_light = dl.light->is_delta(),
                                    .eye_medium = v.in_medium(),
                                    .eye_query_beam = v.query_beam,
                                    .pass_to_light_probability = l.densities.toward_end,
                                    .distance_from_light = l.densities.toward_start,
                                    .eye_photon_beam = eye_photon_beam,
                                    .joint_ratio = joint_ratio,
                                    .eye_joint2 = eye_joint2};
    const float weight = many_lights_ ? 1.0f
                         : joint      ? mis_.weight_joint_direct(eye_mis, technique)
                                      : mis_.weight_direct(eye_mis, technique);
    const Rgb contribution = ls.radiance * f * (weight * v.shading_cos(ls.wi) / dl.pdf_w());
    if (contribution.is_black()) return Rgb(0.0f);
    return contribution * visibility(l, ray, stats);
}

std::optional<ConnectionGeometry> Iteration::connection_geometry(const LightVertex& lv,
                                                                 const Vertex& v, const Vec3& wo) {
    const Vertex& w = lv.vertex;
    Vec3 d = w.p - v.p;
    const float dist2 = length_squared(d);
    if (!(dist2 > 0)) return std::nullopt;
    d = d / std::sqrt(dist2);
    const BsdfEvaluation eye = v.evaluate(wo, d);
    if (eye.f.is_black()) return std::nullopt;
    const BsdfEvaluation light = w.evaluate(lv.wo, -d);
    if (light.f.is_black()) return std::nullopt;
    return ConnectionGeometry{d, dist2, eye, light};
}

std::optional<Iteration::ConnectionTerms> Iteration::connection_terms(
    const LightVertex& lv, const Joint2Vertex& w2, const SubpathVertex& v, const Vec3& wo,
    const MisQuantities& eye_mis, Rng& rng, RenderStats& stats, JointKind joint) const {
    const std::optional<ConnectionGeometry> g = connection_geometry(lv, v, wo);
    if (!g) return std::nullopt;
    const Vertex& w = lv.vertex;
    const Vec3& d = g->d;
    const float dist2 = g->dist2;
    const auto& [f_eye, eye_pdf_w] = g->eye;
    const auto& [f_light, light_pdf_w] = g->light;
    const Ray ray = scene_.spawn_ray_to(v.p, v.n, w.p, w.n);
    const Link l = link(ray, v.medium_toward(wo, d), v.in_medium(), w.in_medium(), rng, stats);
    if (l.traced && l.transmittance.is_black()) return std::nullopt;
    // Densities of extending either subpath to the other's endpoint (area, or volume in a
    // medium, with the distance sampling through media).
    const float eye_pdf_a = eye_pdf_w.forward * w.cos(d) * l.densities.toward_end / dist2;
    const float light_pdf_a = light_pdf_w.forward * v.cos(d) * l.densities.toward_start / dist2;
    // J1 techniques of this junction (the eye vertex sampled toward the light vertex) and of
    // the one before it (the light vertex sampled from the eye vertex toward its predecessor).
    float joint_ratio = 0, light_joint_ratio = 0;
    if (joint_) {
        if (v.joint_distance_pdf > 0)
            joint_ratio = joint_pdf_l(v.previous, v.p, w.p) / v.joint_distance_pdf;
        if (w.in_medium() && joint_light_side(lv.path_length, lv.finite_light) && l.one_piece &&
            l.densities.toward_end > 0)
            light_joint_ratio = joint_pdf_l(v.p, w.p, w.previous) / l.densities.toward_end;
    }
    // J2 of this junction (the light vertex resampled on the emission ray) and of the one
    // before it (the light vertex's predecessor resampled there, the light vertex by J1).
    float joint2_ratio = 0, light_joint2 = 0;
    if (joint_ratio > 0 && w2.light_ray_pdf > 0)
        joint2_ratio = joint2_pdf_l(scene_.bounding_sphere(), w.previous, w.p, v.previous, v.p) /
                       w2.light_ray_pdf;
    if (light_joint_ratio > 0)
        light_joint2 =
            light_joint2_ratio(w2.previous2, w.previous, w2.previous_light_ray_pdf, v.p, w.p);
    // J2 of the junction toward the camera: v resampled on the light ray from w toward it (the
    // connection segment, in one piece), its successor toward the camera by J1.
    float eye_joint2 = 0;
    if (joint2_ && v.camera_joint_ratio > 0 && v.in_medium() && v.medium->is_homogeneous() &&
        l.one_piece && l.densities.toward_start > 0)
        eye_joint2 = mis_.eye_joint2_term(
            eye_mis, v.camera_joint_ratio,
            joint2_pdf_l(scene_.bounding_sphere(), w.p, v.p, v.joint2.previous2, v.previous) /
                l.densities.toward_start);
    // Eqs. (40) and (41).
    const ConnectionTechnique technique{
        .eye_pdf_a = eye_pdf_a,
        .light_pdf_a = light_pdf_a,
        .light_reverse_w = light_pdf_w.reverse,
        .eye_reverse_w = eye_pdf_w.reverse,
        .light_medium = w.in_medium(),
        .eye_medium = v.in_medium(),
        .eye_query_beam = v.query_beam,
        // P-B2D at the light vertex, the connection as the query.
        .light_query_beam =
            w.in_medium() ? mis_.query_beam_term(eye_pdf_w.forward * w.cos(d) / dist2) : 0.0f,
        .light_joint_ratio = light_joint_ratio,
        .joint_ratio = joint_ratio,
        .light_joint2_ratio = light_joint2,
        .joint2_ratio = joint2_ratio,
        .eye_joint2 = eye_joint2,
        // B-B1D at the light vertex (the connection as the query) and at the eye vertex (the
        // connection as the photon beam).
        .light_photon_beam =
            light_photon_beam_term(w, lv.wo, d, eye_pdf_w.forward * w.cos(d) / dist2),
        .eye_photon_beam =
            v.photon_beam > 0
                ? mis_.photon_beam_eye_term(length(cross(wo, d)), v.arrival_distance, v.sigma_t,
                                            light_pdf_a, light_pdf_w.forward * v.cos(d) / dist2,
                                            beam_segment(l.densities))
                : 0.0f};
    const float weight =
        joint == JointKind::J2   ? mis_.weight_joint2_connection(lv.mis, eye_mis, technique)
        : joint == JointKind::J1 ? mis_.weight_joint_connection(lv.mis, eye_mis, technique)
                                 : mis_.weight_connection(lv.mis, eye_mis, technique);
    const float geometry = v.shading_cos(d) * w.shading_cos(d) / dist2;
    const Rgb contribution = f_eye * f_light * (geometry * weight);
    if (contribution.is_black()) return std::nullopt;
    return ConnectionTerms{*g, contribution, ray, l};
}

Rgb Iteration::connect_vertices(const LightVertex& lv, const Joint2Vertex& light_joint2,
                                const SubpathVertex& v, const Vec3& wo,
                                const MisQuantities& eye_mis, Rng& rng, RenderStats& stats) const {
    const std::optional<ConnectionTerms> t =
        connection_terms(lv, light_joint2, v, wo, eye_mis, rng, stats);
    if (!t) return Rgb(0.0f);
    return t->unoccluded * visibility(t->link, t->ray, stats);
}

void Iteration::include_joint_junction(MisQuantities& mis, const SubpathState& state,
                                       SubpathVertex& v) const {
    // The junction's eye-side vertex is the one the eye came from (a medium vertex reached in
    // one piece, else it has no J1 technique), sampled toward v.
    if (!joint_ || !(state.origin_joint_pdf > 0)) return;
    v.camera_joint_ratio =
        joint_pdf_l(state.origin_previous, state.origin, v.p) / state.origin_joint_pdf;
    mis_.include_joint_junction(mis, v.camera_joint_ratio);
}

template <class Add>
void Iteration::joint_connections(const Ray& ray, const SubpathState& state, uint32_t first,
                                  uint32_t end, uint32_t rays_first, uint32_t rays_end, Rng& rng,
                                  RenderStats& stats, Add&& add) const {
    const Medium* medium = state.medium;
    // J1 at s = 1 is next-event estimation's sibling: there whenever next-event estimation is.
    const bool toward_light = 1 + state.path_length <= max_length_;
    if (!medium || (first == end && !toward_light)) return;
    // The segment's first piece ends at the first surface, null or not: J1 samples past it
    // contribute nothing (the technique's density is over the whole half-line, so that every
    // other technique can evaluate it without tracing).
    ++stats.rays;
    const float first_piece = scene_.closest_hit_distance(ray);
    const Vec3 wo = -ray.direction;
    // A medium vertex of the first piece sampled toward `target`: the eye throughput there
    // (transmittance times sigma_s over J1's density), the vertex and the eye subpath's MIS
    // quantities as distance sampling would have produced them (against which J1's weight is
    // taken); nullopt if the sample lies past the first piece or carries nothing.
    struct JointVertex {
        Rgb eye_weight;
        SubpathVertex v;
        MisQuantities mis;
    };
    auto sample_vertex = [&](const Vec3& target) -> std::optional<JointVertex> {
        const HalfLineEquiAngularSampler sampler(state.origin, ray.direction, target);
        const float t = sampler.sample(rng.next_1d());
        const float pdf = sampler.pdf_l(t);
        const Vec3 z = state.origin + ray.direction * t;
        const float t_ray = dot(z - ray.origin, ray.direction);
        if (!(t_ray > 0 && t_ray < first_piece && pdf > 0)) return std::nullopt;
        const Rgb sigma_s = medium->sigma_s(z);
        if (sigma_s.is_black()) return std::nullopt;
        JointVertex j;
        j.eye_weight =
            state.throughput * medium->transmittance(ray, t_ray, rng) * sigma_s * (1.0f / pdf);
        if (j.eye_weight.is_black() || !j.eye_weight.is_finite()) return std::nullopt;
        SegmentDensityBuilder builder(state.in_medium);
        builder.add_piece(medium, ray, t_ray);
        const SegmentDensities densities = builder.finish(true);
        j.v.p = z;
        j.v.medium = medium;
        j.v.phase = &medium->phase();
        j.v.previous = state.origin;
        j.v.joint2.previous2 = state.origin_previous;
        j.v.joint2.previous_light_ray_pdf = state.origin_light_ray_pdf;
        j.v.joint_distance_pdf = densities.toward_end;
        j.mis = state.mis;
        mis_.arrive(j.mis, t_ray * t_ray, true, 1.0f, densities.toward_end, densities.toward_start);
        // As next_vertex: the J2 term of the junction two steps toward the camera, whose light
        // ray would start here (the first piece is one piece).
        if (joint2_ && state.carried_eye_joint2 > 0 && state.origin_in_medium &&
            medium->is_homogeneous())
            mis_.add_eye_joint2_term(j.mis, state.carried_eye_joint2,
                                     joint2_pdf_l(scene_.bounding_sphere(), z, state.origin,
                                                  state.origin_previous2, state.origin_previous),
                                     1.0f, densities.toward_end);
        include_joint_junction(j.mis, state, j.v);
        return j;
    };
    if (toward_light) {
        // J1 at s = 1: a light and a point on it drawn as next-event estimation draws them (the
        // point depends on the numbers alone, Light::sample_position), then the medium vertex
        // sampled toward that point and connected to it with the same numbers.
        DirectLightSample dl;
        dl.light = scene_.sample_light(rng.next_1d(), &dl.pick_probability);
        const Vec2 u = rng.next_2d();
        Vec3 light_point;
        if (dl.light && dl.pick_probability > 0 && dl.light->sample_position(u, light_point)) {
            if (const std::optional<JointVertex> j = sample_vertex(light_point);
                j && dl.light->illuminate(j->v.p, u, dl.ls) && dl.ls.pdf_direct_w > 0)
                add(1, j->eye_weight *
                           direct_contribution(j->mis, j->v, wo, dl, rng, stats, /*joint=*/true));
        }
    }
    // J2: the vertex at the end of each of the pixel's light path's rays (its emission ray and
    // the rays its vertices scattered into, in homogeneous media) resampled on it by B2, then
    // the eye vertex toward it by J1.
    for (uint32_t r = rays_first; r < rays_end; ++r) {
        const LightRay& light_ray = light_rays_[r];
        if (light_ray.path_length + 1 + state.path_length > max_length_) break;
        Joint2Vertex b_joint2;
        if (const std::optional<LightVertex> b =
                resample_on_light_ray(light_ray, state.origin, ray.direction, b_joint2, rng)) {
            if (const std::optional<JointVertex> j = sample_vertex(b->vertex.p)) {
                if (const std::optional<ConnectionTerms> c =
                        connection_terms(*b, b_joint2, j->v, wo, j->mis, rng, stats, JointKind::J2))
                    add(b->path_length + 1, j->eye_weight * b->throughput * c->unoccluded *
                                                visibility(c->link, c->ray, stats));
            }
        }
    }
    for (uint32_t i = first; i < end; ++i) {
        const LightVertex& lv = light_vertices_[i];
        if (lv.path_length + 1 + state.path_length > max_length_) break;
        const std::optional<JointVertex> j = sample_vertex(lv.vertex.p);
        if (!j) continue;
        const std::optional<ConnectionTerms> c =
            connection_terms(lv, joint2_of(i), j->v, wo, j->mis, rng, stats, JointKind::J1);
        if (!c) continue;
        add(lv.path_length + 1,
            j->eye_weight * lv.throughput * c->unoccluded * visibility(c->link, c->ray, stats));
    }
}

std::optional<LightVertex> Iteration::resample_on_light_ray(const LightRay& e,
                                                            const Vec3& eye_origin,
                                                            const Vec3& eye_direction,
                                                            Joint2Vertex& joint2, Rng& rng) const {
    const float range = light_ray_range(scene_.bounding_sphere(), e.origin, e.direction);
    if (!(range > 0)) return std::nullopt;
    const JointLightDistanceSampler b2(e.origin, e.direction, eye_origin, eye_direction, range);
    const float t = b2.sample(rng.next_1d());
    const float pdf = b2.pdf_l(t);
    // Samples past the ray's first piece contribute nothing (B2's density covers the whole
    // range so that every technique evaluates the same density without tracing).
    if (!(pdf > 0 && t > 0 && t < e.piece_end)) return std::nullopt;
    const Medium* medium = e.medium;
    const Ray ray(e.origin, e.direction);
    const Vec3 b = ray.at(t);
    const Rgb sigma_s = medium->sigma_s(b);
    if (sigma_s.is_black()) return std::nullopt;
    // The vertex as if distance sampling had reached it (next_vertex), with B2's density.
    SegmentDensityBuilder builder(e.origin_in_medium);
    builder.add_piece(medium, ray, t);
    const SegmentDensities densities = builder.finish(true);
    LightVertex lv{};
    lv.vertex.p = b;
    lv.vertex.medium = medium;
    lv.vertex.phase = &medium->phase();
    lv.vertex.previous = e.origin;
    lv.vertex.joint_distance_pdf = densities.toward_end;
    joint2 = Joint2Vertex{};
    joint2.previous2 = e.origin_previous;
    joint2.light_ray_pdf = densities.toward_end;
    joint2.previous_light_ray_pdf = e.origin_light_ray_pdf;
    lv.wo = -e.direction;
    lv.throughput = e.throughput * medium->transmittance(ray, t, rng) * sigma_s * (1.0f / pdf);
    if (!lv.throughput.is_finite() || lv.throughput.is_black()) return std::nullopt;
    lv.path_length = e.path_length;
    lv.finite_light = e.finite_light;
    lv.mis = e.mis;
    mis_.arrive(lv.mis, t * t, e.path_length > 1 || e.finite_light, 1.0f, densities.toward_end,
                densities.toward_start);
    // J1's deferred term of the junction whose eye-side vertex is the ray's origin (next_vertex).
    if (e.carried_connection > 0 && e.origin_in_medium &&
        joint_light_side(e.path_length - 1, e.finite_light))
        mis_.add_joint_term(lv.mis, e.carried_connection,
                            joint_pdf_l(b, e.origin, e.origin_previous), 1.0f, densities.toward_end,
                            light_joint2_ratio(e.origin_previous2, e.origin_previous,
                                               e.origin_previous_light_ray_pdf, b, e.origin));
    return lv;
}

Rgb Iteration::vpl_connection(const LightVertex& lv, const Vertex& v, const Vec3& wo, float clamp2,
                              Rng& rng, RenderStats& stats) const {
    const std::optional<ConnectionGeometry> g = connection_geometry(lv, v, wo);
    if (!g) return Rgb(0.0f);
    const Vertex& w = lv.vertex;
    const Vec3& d = g->d;
    // A VPL connection is the only technique for its paths: weight 1, and the estimator
    // averages over the N_L light paths of the iteration.
    const float geometry =
        v.shading_cos(d) * w.shading_cos(d) / std::max(g->dist2, clamp2) * vpl_scale_;
    const Rgb contribution = g->eye.f * g->light.f * geometry;
    if (contribution.is_black()) return Rgb(0.0f);
    const Ray ray = scene_.spawn_ray_to(v.p, v.n, w.p, w.n);
    const Link l = link(ray, v.medium_toward(wo, d), v.in_medium(), w.in_medium(), rng, stats);
    return contribution * visibility(l, ray, stats);
}

std::optional<Iteration::Record> Iteration::trace_record(uint64_t index, RenderStats& stats) const {
    Rng rng(StreamKey{key_.seed, key_.frame, key_.iteration, kRecordStreamBase + index});
    const Vec2 u = rng.next_2d();
    return trace_record_at(Vec2(u.x * float(camera_.width()), u.y * float(camera_.height())), rng,
                           stats);
}

std::optional<Iteration::Record> Iteration::trace_record_at(Vec2 position, Rng& rng,
                                                            RenderStats& stats) const {
    std::vector<Record> records;
    trace_records_at(position, 1, rng, stats, records);
    if (records.empty()) return std::nullopt;
    return std::move(records.front());
}

void Iteration::trace_records_at(Vec2 position, int count, Rng& rng, RenderStats& stats,
                                 std::vector<Record>& out) const {
    const size_t wanted = out.size() + size_t(count);
    Ray ray = camera_.generate_ray(position);
    const Vec3 camera_direction = ray.direction;
    SubpathState state;
    state.throughput = Rgb(1.0f);
    state.mis = mis_.start_camera(camera_pixel_pdf_w(ray.direction));
    state.medium = scene_.camera_medium();
    float distance = 0;
    for (;; ++state.path_length) {
        SampledSegment seg;
        std::optional<SubpathVertex> v =
            next_vertex(ray, TransportMode::Radiance, rng, state, stats, seg);
        if (!v || state.path_length >= max_length_) return;
        distance += seg.distance;
        if (v->has_non_delta()) {
            out.push_back(Record{*v, -ray.direction, state.throughput, state.path_length, distance,
                                 camera_direction, state.mis});
            if (out.size() == wanted) return;
        }
        if (!sample_scattering(*v, -ray.direction, rng, state, ray)) return;
    }
}

std::vector<double> Iteration::estimate_vpl_importance(RenderStats& stats) const {
    std::vector<Record> records;
    for (int j = 0; j < config_.importance_records; ++j)
        if (std::optional<Record> r = trace_record(uint64_t(j), stats)) records.push_back(*r);
    const float clamp2 = record_clamp2();
    std::vector<double> phi(light_vertices_.size(), 0.0);
    tbb::combinable<RenderStats> local_stats;
    using Range = tbb::blocked_range<size_t>;
    tbb::parallel_for(Range(0, light_vertices_.size()), [&](const Range& range) {
        RenderStats& local = local_stats.local();
        for (size_t k = range.begin(); k < range.end(); ++k) {
            const LightVertex& lv = light_vertices_[k];
            Rng rng(StreamKey{key_.seed, key_.frame, key_.iteration, kImportanceStreamBase + k});
            double sum = 0;
            for (const Record& r : records) {
                if (lv.path_length + 1 + r.path_length > max_length_) continue;
                const Rgb c = r.throughput * lv.throughput *
                              vpl_connection(lv, r.vertex, r.wo, clamp2, rng, local);
                const double y = c.luminance();
                if (std::isfinite(y) && y > 0) sum += y;
            }
            phi[k] = sum / double(config_.importance_records);
        }
    });
    local_stats.combine_each([&](const RenderStats& s) { stats += s; });
    return phi;
}

void Iteration::select_vpls(RenderStats& stats, VplSelection* inspection) {
    const size_t candidates = light_vertices_.size();
    stats.vpl_candidates += candidates;
    if (candidates == 0) return;
    const std::vector<double> phi = estimate_vpl_importance(stats);
    // Keep candidate k with P_k (fixed before any draw, so E[kept / P_k] = 1 for each k).
    const std::vector<double> keep = vpl_keep_probabilities(phi, config_.vpl_min_probability);
    BlockVector<LightVertex> kept;
    for (size_t k = 0; k < candidates; ++k) {
        const double p = keep[k];
        Rng rng(StreamKey{key_.seed, key_.frame, key_.iteration, kAcceptStreamBase + k});
        const bool accepted = p >= 1.0 || double(rng.next_1d()) < p;
        if (inspection) {
            const LightVertex& lv = light_vertices_[k];
            inspection->candidates.push_back(VplCandidate{lv.vertex.p, lv.vertex.n, lv.wo,
                                                          lv.vertex.bsdf, lv.throughput,
                                                          lv.path_length, phi[k], p, accepted});
        }
        if (!accepted) continue;
        LightVertex v = light_vertices_[k];
        v.throughput = v.throughput * float(1.0 / p);
        kept.push_back(std::move(v));
    }
    stats.vpl_accepted += kept.size();
    light_vertices_ = std::move(kept);
    path_ends_.clear();  // vpl connects to every vertex; paths are no longer needed
}

IcRecordTables Iteration::record_tables(const Record& r, float radius,
                                        std::span<const uint8_t> mask, Rng& rng,
                                        RenderStats& stats) const {
    const size_t m = ic_vertex_count_;
    std::vector<double> full(m, 0.0), unoccluded(m, 0.0), bounded(m, 0.0);
    const float clamp2 = record_clamp2();
    for (size_t k = 0; k < m; ++k) {
        const LightVertex& lv = light_vertices_[k];
        if (lv.path_length + 1 + r.path_length > max_length_) continue;
        if (ic_connections_) {
            // bpt: the table entries are the connection's own MIS-weighted contribution at the
            // record (the weight tames the 1 / d^2 of nearby vertices, so no clamp).
            const std::optional<ConnectionTerms> t =
                connection_terms(lv, Joint2Vertex{}, r.vertex, r.wo, r.mis, rng, stats);
            if (!t) continue;
            const double y = (lv.throughput * t->unoccluded).luminance();
            if (!(y > 0) || !std::isfinite(y)) continue;
            const Vec3& d = t->geometry.d;
            const double power =
                (lv.throughput * t->geometry.eye.f * t->geometry.light.f).luminance();
            unoccluded[k] = y;
            bounded[k] =
                power * bounded_geometry_factor(std::sqrt(double(t->geometry.dist2)), radius,
                                                lv.vertex.shading_cos(d), r.vertex.shading_cos(d));
            full[k] = y * double(visibility(t->link, t->ray, stats).luminance());
            continue;
        }
        const std::optional<ConnectionGeometry> g = connection_geometry(lv, r.vertex, r.wo);
        if (!g) continue;
        const double cos_record = r.vertex.shading_cos(g->d), cos_vpl = lv.vertex.shading_cos(g->d);
        const double power = (lv.throughput * g->eye.f * g->light.f).luminance();
        if (!(power > 0) || !std::isfinite(power)) continue;
        // The records' own clamp (at least 1 % of the scene radius): a VPL lying on the record
        // must not take the whole table. Tables shape the variance only (C covers every VPL).
        unoccluded[k] = power * cos_record * cos_vpl / std::max(double(g->dist2), double(clamp2));
        bounded[k] = power * bounded_geometry_factor(std::sqrt(double(g->dist2)), radius, cos_vpl,
                                                     cos_record);
        const Ray ray = scene_.spawn_ray_to(r.vertex.p, r.vertex.n, lv.vertex.p, lv.vertex.n);
        const Link l = link(ray, r.vertex.medium_toward(r.wo, g->d), false, false, rng, stats);
        full[k] = unoccluded[k] * double(visibility(l, ray, stats).luminance());
    }
    return make_record_tables(full, unoccluded, bounded, mask);
}

void Iteration::build_importance_cache(RenderStats& stats) {
    // Paths are concatenated in order, so the first ic_light_path_count_ paths' vertices are a
    // prefix of light_vertices_.
    ic_vertex_count_ = path_ends_.empty() ? 0 : path_ends_[ic_light_path_count_ - 1];
    const size_t m = ic_vertex_count_;
    path_ends_.clear();  // importance caching draws from the cached vertices; no paths needed
    ic_weighting_.heuristic = config_.ic_heuristic;
    if (config_.ic_power_only) {
        // The baseline the paper compares with: no records; every shading point draws all
        // 4 n of its VPLs from one distribution proportional to the VPLs' power (its C slot:
        // with no record, the mixture is the fallback alone).
        std::vector<double> power(m);
        for (size_t k = 0; k < m; ++k) power[k] = light_vertices_[k].throughput.luminance();
        ic_fallback_ = ImportanceTable(power);
        ic_samples_ = IcSampleCounts{{0, 0, 0, 4 * config_.ic_samples}};
        return;
    }
    // C: every VPL that carries power, the same mask at every record and in the fallback (a
    // VPL with h(x, v) > 0 anywhere is in it), which keeps the estimator unbiased.
    std::vector<uint8_t> mask(m);
    for (size_t k = 0; k < m; ++k) mask[k] = !light_vertices_[k].throughput.is_black();
    ic_fallback_ = conservative_table(mask);
    ic_samples_ = IcSampleCounts{
        {config_.ic_samples, config_.ic_samples, config_.ic_samples, config_.ic_samples}};
    ic_lookup_.lambda = ic_default_lambda(2.0 * scene_.bounding_sphere().radius);
    if (m == 0) return;

    // The jittered screen grid: square cells of 1 / density pixels, thinned (larger cells) if
    // the tables would exceed kIcTableBytes.
    // ic shades only the first non-delta eye vertex; bpt connects at every eye vertex, so its
    // record paths go on and hold records at their first few non-delta vertices.
    const int per_path = ic_connections_ ? kIcConnectionRecordsPerPath : 1;
    const int width = camera_.width(), height = camera_.height();
    const double table_bytes = 4.0 * double(m + 1) * sizeof(double) * per_path;
    // The density counts records: bpt's record paths are per_path times sparser.
    double cell = 1.0 / std::sqrt(config_.ic_record_density / per_path);
    cell = std::max(cell, std::sqrt(double(width) * height * table_bytes / kIcTableBytes));
    const int nx = std::max(1, int(std::ceil(width / cell))),
              ny = std::max(1, int(std::ceil(height / cell)));
    const float cell_w = float(width) / float(nx), cell_h = float(height) / float(ny);
    std::vector<std::vector<Record>> records(size_t(nx) * size_t(ny));
    std::vector<std::vector<float>> radii(records.size());
    tbb::combinable<RenderStats> local_stats;
    tbb::parallel_for(
        tbb::blocked_range<size_t>(0, records.size()),
        [&](const tbb::blocked_range<size_t>& range) {
            RenderStats& local = local_stats.local();
            for (size_t j = range.begin(); j < range.end(); ++j) {
                Rng rng(StreamKey{key_.seed, key_.frame, key_.iteration, kIcRecordStreamBase + j});
                const Vec2 u = rng.next_2d();
                const Vec2 position((float(j % nx) + u.x) * cell_w, (float(j / nx) + u.y) * cell_h);
                trace_records_at(position, per_path, rng, local, records[j]);
                for (const Record& r : records[j]) {
                    // The region of influence: the disk of the record's cell seen on its
                    // surface (cell solid angle x distance^2 / cos, as an area; along the
                    // path for deeper records, which ignores the spread of the scattering).
                    const double solid_angle =
                        double(cell_w) * cell_h / camera_pixel_pdf_w(r.camera_direction);
                    const double cos_in = std::max(0.1f, r.vertex.cos(r.wo));
                    radii[j].push_back(
                        float(std::sqrt(solid_angle * r.distance * r.distance / cos_in / kPi)));
                }
            }
        });
    std::vector<const Record*> usable;
    std::vector<float> usable_radii;
    std::vector<IcRecordPoint> points;
    for (size_t j = 0; j < records.size(); ++j) {
        for (size_t i = 0; i < records[j].size(); ++i) {
            usable.push_back(&records[j][i]);
            usable_radii.push_back(radii[j][i]);
            points.push_back(IcRecordPoint{records[j][i].vertex.p, records[j][i].vertex.n});
        }
    }
    ic_tables_.resize(usable.size());
    const bool optimise = config_.ic_optimise && config_.ic_heuristic == IcHeuristic::AlphaMax;
    tbb::parallel_for(
        tbb::blocked_range<size_t>(0, usable.size()), [&](const tbb::blocked_range<size_t>& range) {
            RenderStats& local = local_stats.local();
            for (size_t j = range.begin(); j < range.end(); ++j) {
                Rng rng(StreamKey{key_.seed, key_.frame, key_.iteration, kIcTableStreamBase + j});
                ic_tables_[j] = record_tables(*usable[j], usable_radii[j], mask, rng, local);
                if (optimise)
                    ic_tables_[j] =
                        optimise_record_tables(ic_tables_[j], ic_samples_, ic_weighting_.alpha);
            }
        });
    local_stats.combine_each([&](const RenderStats& s) { stats += s; });
    ic_tree_ = IcRecordTree(std::move(points));
}

template <class Term, class Add>
void Iteration::draw_from_importance_caches(const Vertex& v, int eye_length, Rng& rng, Term&& term,
                                            Add&& add) const {
    if (ic_vertex_count_ == 0 || ic_fallback_.empty()) return;
    const IcNeighbours near = ic_tree_.nearest(v.p, v.n, ic_lookup_);
    std::array<const IcRecordTables*, kIcMaxRecords> tables{};
    for (int i = 0; i < near.count; ++i) tables[size_t(i)] = &ic_tables_[near.index[size_t(i)]];
    const IcMixture mixture(
        std::span<const IcRecordTables* const>(tables.data(), size_t(near.count)), ic_fallback_);
    for (IcType t : kIcTypes) {
        if (mixture.empty(t)) continue;
        for (int s = 0; s < ic_samples_[t]; ++s) {
            const double u_record = double(rng.next_1d());
            const size_t k = mixture.sample(t, u_record, next_double(rng));
            const double factor = ic_sample_factor(t, mixture.pmfs(k), ic_samples_, ic_weighting_);
            const LightVertex& lv = light_vertices_[k];
            if (!(factor > 0) || lv.path_length + 1 + eye_length > max_length_) continue;
            add(lv.path_length + 1, term(lv) * float(factor));
        }
    }
}

float Iteration::merge_joint_ratio(const LightVertex& lv, const Vertex& v) const {
    if (!joint_ || !(v.joint_distance_pdf > 0) ||
        !joint_light_side(lv.path_length, lv.finite_light))
        return 0.0f;
    return joint_pdf_l(v.previous, v.p, lv.vertex.previous) / v.joint_distance_pdf;
}

Rgb Iteration::merge(const Vertex& v, const Vec3& wo, const SubpathState& state) const {
    const bool medium = v.in_medium();
    const HashGrid& grid = medium ? medium_grid_ : surface_grid_;
    Rgb sum(0.0f);
    // What a merge reads of a light vertex lies between its wo and its MIS quantities: at most
    // two cache lines.
    auto prefetch = [&](uint32_t i) {
        const LightVertex& lv = light_vertices_[i];
        __builtin_prefetch(&lv.wo);
        __builtin_prefetch(reinterpret_cast<const char*>(&lv.mis + 1) - 1);
    };
    grid.for_each_within_radius(v.p, prefetch, [&](uint32_t i) {
        const LightVertex& lv = light_vertices_[i];
        if (lv.path_length + state.path_length > max_length_) return;
        // The photon arrived from lv.wo; the eye vertex scatters it toward wo.
        const auto [f, pdf_w] = v.evaluate(wo, lv.wo);
        if (f.is_black()) return;
        float weight = 1.0f;
        if (!ppm_) {
            // Eqs. (38) and (39).
            weight = mis_.weight_merge(
                lv.mis, state.mis,
                {.eye_forward_w = pdf_w.forward,
                 .eye_reverse_w = pdf_w.reverse,
                 .medium = medium,
                 .query_beam = v.query_beam,
                 .photon_beam = v.photon_beam > 0 && lv.vertex.photon_beam > 0
                                    ? mis_.photon_beam_merge_term(length(cross(wo, lv.wo)),
                                                                  lv.vertex.arrival_distance,
                                                                  v.arrival_distance, v.sigma_t)
                                    : 0.0f,
                 .light_joint_ratio = merge_joint_ratio(lv, v)});
        }
        Rgb photon = lv.throughput;
        if (medium) {
            // Both subpaths' throughputs carry sigma_s at their medium vertex (the distance
            // sampling weight); the merged path scatters once, so one of them is divided out.
            const Rgb sigma_s = lv.vertex.medium->sigma_s(lv.vertex.p);
            for (int c = 0; c < 3; ++c) photon[c] = sigma_s[c] > 0 ? photon[c] / sigma_s[c] : 0.0f;
        }
        sum += f * photon * weight;
    });
    return sum * (medium ? vm_normalization_volume_ : vm_normalization_);
}

Rgb Iteration::query_beams(const Ray& ray, const SubpathState& state, Rng& rng,
                           RenderStats& stats) const {
    Rgb sum(0.0f);
    if (medium_positions_.empty()) return sum;
    for_each_eye_medium_piece(ray, state, rng, stats,
                              [&](const Medium* medium, const Ray& piece, float t_end,
                                  const SegmentDensityBuilder& before, const Rgb& transmittance) {
                                  query_beams_in_piece(ray, state, medium, piece, t_end, before,
                                                       transmittance, rng, sum);
                              });
    return sum * beam_normalization_;
}

void Iteration::query_beams_in_piece(const Ray& ray, const SubpathState& state,
                                     const Medium* medium, const Ray& piece, float t_end,
                                     const SegmentDensityBuilder& before, const Rgb& transmittance,
                                     Rng& rng, Rgb& sum) const {
    const PointsAlongRay& lookup = *storage_.beam_lookup;
    // sigma_s at the photon's projection over sigma_s at the photon: 1 in a homogeneous
    // medium, whose look-ups are skipped.
    const bool homogeneous = medium->is_homogeneous();
    Ray query = piece;
    query.t_max = t_end;
    lookup.for_each_near(query, [&](uint32_t i, float t, float) {
        const LightVertex& lv = light_vertices_[medium_index_[i]];
        if (lv.vertex.medium != medium) return;  // a photon of another medium
        if (lv.path_length + state.path_length > max_length_) return;
        const Vec3 x = piece.at(t);
        const float p = lv.vertex.phase->p(-ray.direction, lv.wo);
        if (!(p > 0)) return;
        // The eye subpath as if it had scattered at x (the query's distance density
        // goes to the weight: vcm_mis.h, weight_query_beam).
        SegmentDensityBuilder densities = before;
        densities.add_piece(medium, piece, t);
        const SegmentDensities d = densities.finish(true);
        MisQuantities eye = state.mis;
        mis_.arrive(eye, length_squared(x - ray.origin), true, 1.0f, 1.0f, d.toward_start);
        mis_.add_photon_beam_term(eye, state.carried_photon_beam, 1.0f, 1.0f, d.toward_start, true,
                                  beam_segment(d));
        const float weight = mis_.weight_query_beam(
            lv.mis, eye, d.toward_end,
            {.eye_forward_w = p,
             .eye_reverse_w = p,
             .medium = true,
             .photon_beam = light_photon_beam_term(lv.vertex, lv.wo, ray.direction, 1.0f)});
        // sigma_s at x scatters the eye's light; the photon's throughput carries its
        // own vertex's sigma_s (its distance sampling), divided out.
        Rgb photon = lv.throughput;
        if (!homogeneous) {
            const Rgb sigma_query = medium->sigma_s(x);
            const Rgb sigma_photon = medium->sigma_s(lv.vertex.p);
            for (int c = 0; c < 3; ++c)
                photon[c] =
                    sigma_photon[c] > 0 ? photon[c] * sigma_query[c] / sigma_photon[c] : 0.0f;
        }
        const Rgb tr = transmittance * medium->transmittance(piece, t, rng);
        sum += tr * photon * (p * weight);
    });
}

template <typename Visit>
void Iteration::for_each_eye_medium_piece(const Ray& ray, const SubpathState& state, Rng& rng,
                                          RenderStats& stats, Visit&& visit) const {
    SegmentDensityBuilder before(state.in_medium);
    Rgb transmittance(1.0f);
    const Medium* medium = state.medium;
    Ray piece = ray;
    for (int crossing = 0; crossing <= kMaxNullCrossings; ++crossing) {
        SurfaceInteraction si;
        ++stats.rays;
        const bool hit = scene_.intersect(piece, si);
        const float t_end = hit ? si.t : kInfinity;
        if (medium) {
            visit(medium, piece, t_end, before, transmittance);
            transmittance *= medium->transmittance(piece, t_end, rng);
        }
        if (!hit || !si.bsdf->is_null() || transmittance.is_black()) break;
        before.add_piece(medium, piece, si.t);
        medium = medium_after_transmission(si, piece.direction);
        piece = scene_.spawn_ray(si.p, si.geometric_normal, piece.direction);
    }
}

// --- photon beams (B-B1D) ---------------------------------------------------------------------

namespace {

// What a photon beam carries to its closest approach t along its last piece: the transmittance
// (long beams: exact in a homogeneous medium, ratio tracking in a grid, drawing from the query's
// numbers) or, for short beams, the transmittance over the probability that the sampled distance
// passed t (exact in a homogeneous medium; exactly 1 where the pass weight is one), or in a
// chromatic grid the sampling walk's pass weight at t, replayed from its random state (an
// unbiased weight: E[w(t) 1{passed t}] = T(t), Medium::replay_pass_weight).
Rgb beam_transmittance(const Medium* medium, const Ray& beam, float t, bool short_beams,
                       const PhotonBeam& b, Rng& rng) {
    if (short_beams && !medium->is_homogeneous())
        return medium->pass_weight_is_one()
                   ? Rgb(1.0f)
                   : medium->replay_pass_weight(beam, b.replay_t_max, t, b.replay);
    const Rgb tr = medium->transmittance(beam, t, rng);  // homogeneous: exact, draws nothing
    if (!short_beams) return tr;
    return tr / std::max(medium->probability_pass(beam, t), 1e-35f);
}

}  // namespace

// Photon beams are clipped at this length where a light subpath leaves the scene inside an
// unbounded medium: no vertex a ray can reach lies farther (core/base/scene_limits.h).
constexpr float kMaxPhotonBeamLength = 4 * kMaxSceneCoordinate;

void Iteration::emit_photon_beams(const Ray& ray, const SubpathState& from,
                                  const SampledSegment& seg, uint64_t path_index, uint32_t& piece,
                                  Rng& rng, RenderStats& stats) const {
    const bool short_beams = config_.short_photon_beams;
    std::vector<PhotonBeam>& out = storage_.photon_beam_staging.local();
    PhotonBeam beam;
    beam.line.direction = ray.direction;
    beam.weight = from.throughput;
    beam.before = SegmentDensityBuilder(from.in_medium);
    beam.mis = from.mis;
    beam.carried_query_beam = from.carried_query_beam;
    beam.carried_photon_beam = from.carried_photon_beam;
    beam.path_length = from.path_length;
    beam.apply_distance = from.path_length > 1 || from.is_finite_light;
    auto emit = [&](const Ray& r, const Medium* medium, float length, float offset) {
        beam.order = (path_index << 24) | std::min<uint32_t>(piece++, (1u << 24) - 1);
        beam.line.origin = r.origin;
        beam.line.length = std::min(length, kMaxPhotonBeamLength);
        beam.medium = medium;
        beam.offset = offset;
        out.push_back(beam);
    };
    const Medium* medium = from.medium;
    // One piece that ends where the sample ended (short beams, or any beam ending at a
    // surface): the segment already traced it.
    if (seg.one_piece && seg.end != SegmentEnd::Escaped &&
        (short_beams || seg.end == SegmentEnd::Surface)) {
        if (!medium) return;
        if (replays_walk(medium)) {
            if (!seg.first_piece_rng) return;
            beam.replay = *seg.first_piece_rng;
            beam.replay_t_max = seg.first_piece_t_max;
        }
        emit(ray, medium, seg.distance, 0.0f);
        return;
    }
    // Otherwise walk the pieces again (the same closest hits as the sampling saw), up to the
    // sampled distance (short) or the first surface that is not a null boundary (long). A piece
    // where beams of this length cannot live (short beams in a chromatic grid past the first
    // piece: they would need that piece's whole pass weight) ends the walk, and beam_segment
    // tells the weights so. A grid piece's transmittance is estimated
    // by ratio tracking with numbers of its own (the light path's stay as they were).
    Rng beam_rng(
        StreamKey{key_.seed, key_.frame, key_.iteration,
                  kPhotonBeamStreamBase + (path_index << 8) + uint64_t(from.path_length & 0xff)});
    Ray r = ray;
    float offset = 0;
    for (int crossing = 0; crossing <= kMaxNullCrossings; ++crossing) {
        SurfaceInteraction si;
        ++stats.rays;
        const bool hit = scene_.intersect(r, si);
        const float t_end = hit ? si.t : kInfinity;
        float end = t_end;
        bool last = !hit || !si.bsdf->is_null();
        if (short_beams && seg.end != SegmentEnd::Escaped) {
            const float t_sample = dot(seg.position - r.origin, r.direction);
            if (t_sample <= t_end) {
                end = std::max(t_sample, 0.0f);
                last = true;
            }
        }
        if (medium) {
            if (replays_walk(medium)) {
                // Only as the segment's first piece, and nothing after it (beam_segment).
                if (crossing > 0 || !seg.first_piece_rng) return;
                beam.replay = *seg.first_piece_rng;
                beam.replay_t_max = seg.first_piece_t_max;
                emit(r, medium, end, offset);
                return;
            }
            emit(r, medium, end, offset);
            if (last) return;
            // Passing this piece: its transmittance, over the probability that the sample
            // passed it for a short beam (which reached the next piece only if it did). That
            // ratio is exact in a homogeneous medium and exactly 1 where the pass weight is one
            // (grey grids: delta tracking passes with probability T); a long beam's is the
            // transmittance, exact or (grids) an unbiased ratio-tracking estimate.
            if (short_beams) {
                if (medium->is_homogeneous()) {
                    const Rgb tr = medium->transmittance(r, t_end, rng);  // exact: draws nothing
                    beam.weight *= tr / std::max(medium->probability_pass(r, t_end), 1e-35f);
                }
            } else {
                beam.weight *= medium->transmittance(r, t_end, beam_rng);
            }
            if (beam.weight.is_black()) return;
        }
        if (last) return;
        beam.before.add_piece(medium, r, t_end);
        offset += t_end;
        medium = medium_after_transmission(si, r.direction);
        r = scene_.spawn_ray(si.p, si.geometric_normal, r.direction);
    }
}

void Iteration::build_photon_beams() {
    std::vector<PhotonBeam>& beams = storage_.photon_beams;
    beams.clear();
    for (std::vector<PhotonBeam>& staged : storage_.photon_beam_staging) {
        beams.insert(beams.end(), staged.begin(), staged.end());
        staged.clear();
    }
    std::sort(beams.begin(), beams.end(),
              [](const PhotonBeam& a, const PhotonBeam& b) { return a.order < b.order; });
    std::vector<BeamLine>& lines = storage_.photon_beam_lines;
    lines.clear();
    lines.reserve(beams.size());
    for (const PhotonBeam& b : beams) lines.push_back(b.line);
    const float r = float(photon_beam_radius_);
    Aabb box = scene_.bounds();
    box.lo = box.lo - Vec3(r);
    box.hi = box.hi + Vec3(r);
    auto inside = [&](const Vec3& p) {
        return p.x >= box.lo.x && p.y >= box.lo.y && p.z >= box.lo.z && p.x <= box.hi.x &&
               p.y <= box.hi.y && p.z <= box.hi.z;
    };
    storage_.photon_beams_in_grid =
        !box.empty() && std::all_of(lines.begin(), lines.end(), [&](const BeamLine& b) {
            return inside(b.origin) && inside(b.origin + b.direction * b.length);
        });
    if (storage_.photon_beams_in_grid) {
        storage_.photon_beam_grid.build(lines, r, box);
        return;
    }
    if (!storage_.photon_beam_lookup)
        storage_.photon_beam_lookup = std::make_unique<BeamsAlongRay>();
    storage_.photon_beam_lookup->build(lines, r);
}

Rgb Iteration::photon_beams(const Ray& ray, const SubpathState& state, Rng& rng,
                            RenderStats& stats) const {
    Rgb sum(0.0f);
    if (storage_.photon_beams.empty()) return sum;
    for_each_eye_medium_piece(ray, state, rng, stats,
                              [&](const Medium* medium, const Ray& piece, float t_end,
                                  const SegmentDensityBuilder& before, const Rgb& transmittance) {
                                  photon_beams_in_piece(ray, state, medium, piece, t_end, before,
                                                        transmittance, rng, sum);
                              });
    return sum * photon_beam_normalization_;
}

void Iteration::both_beams(const Ray& ray, const SubpathState& state, Rng& rng, RenderStats& stats,
                           Rgb& query_sum, Rgb& photon_sum) const {
    query_sum = photon_sum = Rgb(0.0f);
    const bool points = !medium_positions_.empty(), beams = !storage_.photon_beams.empty();
    if (!points && !beams) return;
    for_each_eye_medium_piece(ray, state, rng, stats,
                              [&](const Medium* medium, const Ray& piece, float t_end,
                                  const SegmentDensityBuilder& before, const Rgb& transmittance) {
                                  if (points)
                                      query_beams_in_piece(ray, state, medium, piece, t_end, before,
                                                           transmittance, rng, query_sum);
                                  if (beams)
                                      photon_beams_in_piece(ray, state, medium, piece, t_end,
                                                            before, transmittance, rng, photon_sum);
                              });
    query_sum = query_sum * beam_normalization_;
    photon_sum = photon_sum * photon_beam_normalization_;
}

void Iteration::photon_beams_in_piece(const Ray& ray, const SubpathState& state,
                                      const Medium* medium, const Ray& piece, float t_end,
                                      const SegmentDensityBuilder& before, const Rgb& transmittance,
                                      Rng& rng, Rgb& sum) const {
    const std::vector<PhotonBeam>& beams = storage_.photon_beams;
    const bool short_beams = config_.short_photon_beams;
    {
        Ray query = piece;
        query.t_max = t_end;
        auto gather = [&](uint32_t i, const BeamApproach& a) {
            const PhotonBeam& b = beams[i];
            if (b.medium != medium) return;  // a beam of another medium
            if (b.path_length + state.path_length > max_length_) return;
            const Vec3 x = piece.at(a.t_ray);
            const float sigma_t = medium->sigma_t(x).average();
            if (!(sigma_t > 0)) return;
            // The eye scatters the beam's light toward the camera at x.
            const float p = medium->phase().p(-ray.direction, -b.line.direction);
            if (!(p > 0)) return;
            // Both subpaths as if they had arrived at the closest approach, their distance
            // densities left to the weight (vcm_mis.h, weight_photon_beam).
            const Ray beam_ray(b.line.origin, b.line.direction);
            SegmentDensityBuilder light_pieces = b.before;
            light_pieces.add_piece(medium, beam_ray, a.t_beam);
            const SegmentDensities dl = light_pieces.finish(true);
            MisQuantities light = b.mis;
            const float light_distance = b.offset + a.t_beam;
            mis_.arrive(light, light_distance * light_distance, b.apply_distance, 1.0f, 1.0f,
                        dl.toward_start);
            mis_.add_query_beam_term(light, b.carried_query_beam, 1.0f, 1.0f);
            mis_.add_photon_beam_term(light, b.carried_photon_beam, 1.0f, 1.0f, dl.toward_start,
                                      false, true);
            SegmentDensityBuilder eye_pieces = before;
            eye_pieces.add_piece(medium, piece, a.t_ray);
            const SegmentDensities dc = eye_pieces.finish(true);
            MisQuantities eye = state.mis;
            mis_.arrive(eye, length_squared(x - ray.origin), true, 1.0f, 1.0f, dc.toward_start);
            mis_.add_photon_beam_term(eye, state.carried_photon_beam, 1.0f, 1.0f, dc.toward_start,
                                      true, beam_segment(dc));
            const float weight = mis_.weight_photon_beam(
                light, eye, dl.toward_end, dc.toward_end, a.sin_theta, sigma_t,
                {.eye_forward_w = p, .eye_reverse_w = p, .medium = true});
            if (!(weight > 0)) return;
            // The beam's transmittance to the closest approach (over the probability that
            // a short beam reaches it), the query's, sigma_s and the phase function at x,
            // and the kernel's 1 / sin(theta), formed as weight / sin(theta): the weight
            // is proportional to sin(theta) (ALGORITHMS-NEXT.md 4.4).
            const Rgb beam_tr = beam_transmittance(medium, beam_ray, a.t_beam, short_beams, b, rng);
            const Rgb tr = transmittance * medium->transmittance(piece, a.t_ray, rng);
            sum += tr * beam_tr * b.weight * medium->sigma_s(x) * (p * (weight / a.sin_theta));
        };
        if (storage_.photon_beams_in_grid)
            storage_.photon_beam_grid.for_each_near(query, gather);
        else
            storage_.photon_beam_lookup->for_each_near(query, gather);
    }
}

Rgb Iteration::trace_eye_path(uint64_t pixel, RenderStats& stats, const LayerSink& sink) const {
    Rng rng(StreamKey{key_.seed, key_.frame, key_.iteration, pixel});
    const int width = camera_.width();
    const Vec2 jitter = rng.next_2d();
    Ray ray = camera_.generate_ray(
        Vec2(float(pixel % width) + jitter.x, float(pixel / width) + jitter.y));
    SubpathState state;
    state.throughput = Rgb(1.0f);
    state.initial_luminance = 1.0f;
    state.mis = mis_.start_camera(camera_pixel_pdf_w(ray.direction));
    state.medium = scene_.camera_medium();
    state.origin = ray.origin;

    Rgb color(0.0f);
    // s light vertices and t = path_length + 1 eye vertices (the camera included).
    auto add = [&](Technique kind, int s, const Rgb& contribution) {
        color += contribution;
        sink.add(kind, s, state.path_length + 1, contribution);
    };
    // The pixel's light path (connections and joint connections).
    uint32_t light_first = 0, light_end = 0;
    uint32_t rays_first = 0, rays_end = 0;  // its J2 light rays
    if (use_vc_ && !ic_connections_ && !path_ends_.empty()) {
        const uint64_t path = pixel % light_path_count_;
        light_first = path == 0 ? 0 : path_ends_[path - 1];
        light_end = path_ends_[path];
        if (path < ray_ends_.size()) {
            rays_first = path == 0 ? 0 : ray_ends_[path - 1];
            rays_end = ray_ends_[path];
        }
    }
    for (;; ++state.path_length) {
        if (joint_ && state.path_length < max_length_)
            joint_connections(ray, state, light_first, light_end, rays_first, rays_end, rng, stats,
                              [&](int s, const Rgb& c) { add(Technique::Connection, s, c); });
        if (query_beams_ && photon_beams_ && state.path_length < max_length_) {
            Rgb query_sum, photon_sum;
            both_beams(ray, state, rng, stats, query_sum, photon_sum);
            add(Technique::Merging, 0, state.throughput * query_sum);
            add(Technique::Merging, 0, state.throughput * photon_sum);
        } else if (query_beams_ && state.path_length < max_length_) {
            add(Technique::Merging, 0, state.throughput * query_beams(ray, state, rng, stats));
        } else if (photon_beams_ && state.path_length < max_length_) {
            add(Technique::Merging, 0, state.throughput * photon_beams(ray, state, rng, stats));
        }
        SampledSegment seg;
        std::optional<SubpathVertex> v =
            next_vertex(ray, TransportMode::Radiance, rng, state, stats, seg);
        if (!v) {
            if (seg.end == SegmentEnd::Escaped && !state.throughput.is_black()) {
                // Left the scene: the distance sampling on the way is part of this
                // technique's density; an infinite light has no distance or cosine term.
                mis_.arrive(state.mis, 0.0f, false, 1.0f, seg.densities.toward_end,
                            seg.densities.toward_start);
                mis_.add_photon_beam_term(state.mis, state.carried_photon_beam, 1.0f,
                                          seg.densities.toward_end, seg.densities.toward_start,
                                          true, beam_segment(seg.densities));
                for (const Light* light : scene_.background_lights())
                    add(Technique::Connection, 0,
                        state.throughput * emission(light, state, Vec3(), Vec3(), ray.direction));
            }
            break;
        }
        const Vec3 wo = -ray.direction;
        if (!v->in_medium() && seg.si.emitter)
            add(Technique::Connection, 0,
                state.throughput * emission(seg.si.emitter, state, v->p, v->n, ray.direction));
        if (v->in_medium() && v->medium->is_emissive() && !scene_.volume_lights().empty()) {
            add(Technique::Connection, 0, medium_emission(state, *v));
            if (state.throughput.is_black()) break;  // nothing scatters here (albedo 0)
        }
        if (state.path_length >= max_length_) break;
        // Every technique below treats v as a scattering vertex (emission above: as the light).
        include_joint_junction(state.mis, state, *v);

        // Light tracing and PPM leave every non-delta scattering of the eye path to the light
        // paths (camera connections or the one merge); the eye continues only through delta
        // lobes, including the delta lobes of mixed materials such as plastic's coating.
        const bool eye_ends_at_non_delta = light_trace_only_ || ppm_ || many_lights_;
        if (v->has_non_delta() && !light_trace_only_) {
            if (many_lights_) {
                add(Technique::Connection, 1,
                    state.throughput * direct_illumination(state, *v, wo, rng, stats));
            }
            if (ic_) {
                draw_from_importance_caches(
                    *v, state.path_length, rng,
                    [&](const LightVertex& lv) {
                        return lv.throughput * vpl_connection(lv, *v, wo, vpl_clamp2_, rng, stats);
                    },
                    [&](int s, const Rgb& c) {
                        add(Technique::Connection, s, state.throughput * c);
                    });
            }
            if (vpl_) {
                for (const LightVertex& lv : light_vertices_) {
                    if (lv.path_length + 1 + state.path_length > max_length_) continue;
                    add(Technique::Connection, lv.path_length + 1,
                        state.throughput * lv.throughput *
                            vpl_connection(lv, *v, wo, vpl_clamp2_, rng, stats));
                }
            }
            if (use_vc_) {
                add(Technique::Connection, 1,
                    state.throughput * direct_illumination(state, *v, wo, rng, stats));
            }
            if (ic_connections_) {
                // (1 / N) sum over the N cached light paths of their connections to v: its
                // expectation is one light path's, so every MIS weight stays as it is.
                draw_from_importance_caches(
                    *v, state.path_length, rng,
                    [&](const LightVertex& lv) {
                        // No J2 beside ic connections (joint_ is off there).
                        return lv.throughput *
                               connect_vertices(lv, Joint2Vertex{}, *v, wo, state.mis, rng, stats) *
                               ic_connection_scale_;
                    },
                    [&](int s, const Rgb& c) {
                        add(Technique::Connection, s, state.throughput * c);
                    });
            } else if (use_vc_) {
                for (uint32_t i = light_first; i < light_end; ++i) {
                    const LightVertex& lv = light_vertices_[i];
                    if (lv.path_length + 1 + state.path_length > max_length_) break;
                    add(Technique::Connection, lv.path_length + 1,
                        state.throughput * lv.throughput *
                            connect_vertices(lv, joint2_of(i), *v, wo, state.mis, rng, stats));
                }
            }
            if (v->in_medium() ? merge_points_ : merge_surfaces_) {
                add(Technique::Merging, 0, state.throughput * merge(*v, wo, state));
            }
        }
        if (eye_ends_at_non_delta && !v->has_delta()) break;
        if (!sample_scattering(*v, wo, rng, state, ray)) break;
        if (eye_ends_at_non_delta && !state.specular_path) break;
    }
    return color;
}

}  // namespace

VertexConnectionMerging::VertexConnectionMerging(const BidirectionalConfig& config)
    : config_(config), storage_(std::make_unique<IterationStorage>()) {}

VertexConnectionMerging::~VertexConnectionMerging() = default;

void VertexConnectionMerging::render_iteration(const Scene& scene, const IterationKey& key,
                                               AccumulationBuffer& target, TechniqueLayers* layers,
                                               RenderStats& stats) const {
    std::lock_guard lock(storage_mutex_);
    Iteration iteration(config_, scene, key, *storage_);
    if (!scene.lights().empty() || !scene.volume_lights().empty()) {
        // The light tracer's splats reach the image in chunk order and before the eye pass's
        // estimates, so that each pixel's sum is the same whatever the number of threads.
        iteration.trace_light_paths(stats, [&](std::span<const Splat> splats) {
            for (const Splat& splat : splats) {
                if (!splat.value.is_finite()) {
                    ++stats.non_finite;
                    continue;
                }
                target.add(splat.pixel, splat.value);
                if (layers)
                    layers->add(layers->index(Technique::Connection, splat.light_vertices, 1),
                                splat.pixel, splat.value);
            }
        });
        if (config_.mode == BidirectionalMode::Vpl && config_.vpl_importance)
            iteration.select_vpls(stats);
        if (iteration.uses_importance_caches()) iteration.build_importance_cache(stats);
    }

    const int width = scene.camera().width(), height = scene.camera().height();
    for_each_pixel(width, height, target, stats, [&](uint64_t pixel, RenderStats& local) {
        return iteration.trace_eye_path(pixel, local, LayerSink{layers, pixel});
    });
}

VplSelection VertexConnectionMerging::inspect_vpl_selection(const Scene& scene,
                                                            const IterationKey& key) const {
    VplSelection selection;
    if (config_.mode != BidirectionalMode::Vpl || !config_.vpl_importance || scene.lights().empty())
        return selection;
    IterationStorage storage;
    Iteration iteration(config_, scene, key, storage);
    RenderStats stats;
    iteration.trace_light_paths(stats, [](std::span<const Splat>) {});
    iteration.select_vpls(stats, &selection);
    selection.light_paths = iteration.light_path_count();
    selection.importance_records = config_.importance_records;
    selection.record_distance_clamp = std::sqrt(double(iteration.record_clamp2()));
    return selection;
}

PhotonBeamInspection VertexConnectionMerging::inspect_photon_beams(const Scene& scene,
                                                                   const IterationKey& key) const {
    PhotonBeamInspection out;
    if (config_.mode != BidirectionalMode::Vcm || !config_.photon_beams ||
        (scene.lights().empty() && scene.volume_lights().empty()))
        return out;
    IterationStorage storage;
    Iteration iteration(config_, scene, key, storage);
    RenderStats stats;
    iteration.trace_light_paths(stats, [](std::span<const Splat>) {});
    out.lines = storage.photon_beam_lines;
    out.radius = iteration.photon_beam_radius();
    return out;
}

}  // namespace render
