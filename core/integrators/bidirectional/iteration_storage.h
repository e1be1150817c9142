#pragma once

// The buffers of an iteration that an integrator keeps from one iteration to the next (cleared,
// capacity kept): the stored light vertices and their side arrays, the light pass's chunks, the
// merging grids and the beams' lookups.

#include <functional>
#include <memory>
#include <mutex>
#include <span>
#include <vector>

#include <tbb/enumerable_thread_specific.h>

#include "core/base/render_stats.h"
#include "core/integrators/beam_grid.h"
#include "core/integrators/beams_along_ray.h"
#include "core/integrators/bidirectional/subpath.h"
#include "core/integrators/hash_grid.h"
#include "core/integrators/points_along_ray.h"
#include "core/sampling/rng.h"
#include "core/util/block_vector.h"

namespace render::bidirectional {

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

// What the camera's medium rule reads of a stored light vertex, kept beside it (a LightVertex is
// two cache lines and has no room): the medium the subpath arrived in and, at a surface, the
// surface's shape, whose declaration decides whether the medium goes on through it.
struct LightVertexMedia {
    const Medium* arrival = nullptr;
    const Shape* shape = nullptr;  // null in a medium
};

// One thread's photon beams while the light paths are traced (IterationStorage).
struct PhotonBeamStaging {
    std::vector<PhotonBeam> beams;
    // Empty until one of the thread's beams replays; from then on one per beam (the beams before
    // it get a default one that nothing reads).
    std::vector<BeamReplay> replays;
};

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
              "LightRay outgrew kLightRayBytesBound (record_bounds.h): raise it");

// One chunk of light paths, from its tracing (in parallel with other chunks) to its gathering
// into the iteration's arrays (in chunk order).
struct LightChunk {
    uint64_t index = 0;
    std::vector<LightVertex> vertices;
    std::vector<uint32_t> path_sizes;             // vertices kept per path
    std::vector<LightRay> light_rays;             // with J2, else none
    std::vector<uint32_t> ray_counts;             // light rays per path, with J2
    std::vector<Joint2Vertex> joint2_vertices;    // one per vertex with J2, else none
    std::vector<LightVertexMedia> arrival_media;  // one per vertex under the rule, else none
    std::vector<Splat> splats;
    RenderStats stats;
};

using SplatSink = std::function<void(std::span<const Splat>)>;

// What an integrator keeps of its iterations (cleared by each Iteration, capacity kept).
struct IterationStorage {
    // In blocks: gathering a chunk appends without ever moving the vertices already there.
    BlockVector<LightVertex> light_vertices;
    std::vector<uint32_t> path_ends;
    // J2's light rays, and where each light path's end (like path_ends), with J2; else empty.
    std::vector<LightRay> light_rays;
    std::vector<uint32_t> ray_ends;
    // J2's state of each light vertex, indexed like light_vertices (with J2; else empty).
    BlockVector<Joint2Vertex> joint2_vertices;
    // Each light vertex's media, indexed like light_vertices, under the camera's medium rule
    // (IterationPlan::camera_medium_rule); else empty.
    BlockVector<LightVertexMedia> light_vertex_media;
    // The light pass's chunk buffers (a few per thread), reused from one iteration to the next.
    std::vector<std::unique_ptr<LightChunk>> light_chunks;
    std::vector<LightChunk*> free_light_chunks;
    std::mutex light_chunks_mutex;
    std::vector<Vec3> medium_positions;
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
    // docs/design/media.md), or the BVH in an iteration where a beam leaves the scene's box (a beam
    // escaping through an unbounded medium: the grid would have to span it).
    UniformBeamGrid photon_beam_grid;
    std::unique_ptr<BeamsAlongRay> photon_beam_lookup;
    bool photon_beams_in_grid = false;
};

// An integrator's IterationStorage, kept from one render_iteration to the next (cleared, capacity
// kept) so that iterations after the first do not fault in hundreds of MB of fresh pages; calls
// on one integrator from several threads take turns (run_iteration holds the mutex).
struct KeptStorage {
    std::mutex mutex;
    IterationStorage storage;
};

}  // namespace render::bidirectional
