#include "core/render/iteration_memory.h"

#include <algorithm>
#include <thread>

#include "core/base/memory_budget.h"
#include "core/integrators/bidirectional/record_bounds.h"
#include "core/render/algorithms.h"

namespace render {

namespace {

using namespace bidirectional;  // the record bounds

// Sizes of the iteration's stored records: bounds its headers check with static_assert.
// A stored light vertex (LightVertex: the vertex, its direction, throughput and MIS values).
constexpr uint64_t kLightVertexBytes = kLightVertexBytesBound;
// A photon beam (PhotonBeam), its line for the lookup (BeamLine) and its references in the
// lookup's uniform grid (beam_grid.h: 4 B each; measured 31-59 per beam on isosph and the
// smoke, docs/design/media.md), with the grid's per-cell arrays (about one cell per beam).
constexpr uint64_t kPhotonBeamBytes = kPhotonBeamBytesBound + 32 + 64 * 4 + 12;
// Merging modes, per stored vertex: its position and index (16 B) in vectors that grow by
// doubling (x 2), and the hash grid's entry (position and index, 16 B) and cell start; in a
// scene with media, the medium the vertex arrived in (8 B, IterationStorage::light_vertex_media;
// the estimate does not see the scene's media, so it charges it wherever merges are on).
constexpr uint64_t kMergeIndexBytes = 60;
// upbp, per stored vertex (any of them may lie in a medium): a photon beam, and the query
// beams' Embree BVH over the medium vertices as balls (~128 B per primitive).
constexpr uint64_t kVolumeEstimatorBytes = kPhotonBeamBytes + 128;
// Short photon beams in a chromatic grid keep their walk's replay state beside them
// (BeamReplay, one per beam in such an iteration). The estimate does not see the scene's media,
// so it charges it wherever short beams are on.
constexpr uint64_t kBeamReplayBytes = kBeamReplayBytesBound;
// The light pass's chunks (bidirectional/light_pass.cpp: 256 light paths each, 4 in flight per
// thread), whose vertices are copied into the iteration's arrays.
constexpr uint64_t kLightPathsPerChunk = 256;
constexpr uint64_t kChunksInFlightPerThread = 4;
// Each thread's own buffers whatever the algorithm: tiles, sample arenas, Embree's ray
// contexts and TBB's bookkeeping (too small to see in the peaks at 1 and 2 threads, where a
// 128x128 pt render's whole growth above the process's base is 0.5 MiB; an allowance for
// machines of many cores).
constexpr uint64_t kPerThreadBytes = 1ull << 20;
// ic and bpt's importance-cached connections: per record and light vertex, four cumulative
// tables of doubles (importance_table.h).
constexpr uint64_t kImportanceTableBytes = 4 * sizeof(double);

uint64_t add(uint64_t a, uint64_t b) {
    return a > UINT64_MAX - b ? UINT64_MAX : a + b;
}

uint64_t mul(uint64_t a, uint64_t b) {
    return saturating_product(a, b);
}

}  // namespace

uint64_t assumed_light_vertices_per_path(const RenderSettings& settings) {
    const uint64_t roulette = uint64_t(std::max(settings.rr_depth, 0)) + kRouletteTailVertices;
    // A light subpath stores its vertices 1 .. max_depth - 1 (the last segment goes to the eye).
    if (settings.max_depth < 0) return roulette;
    return std::min(uint64_t(std::max(settings.max_depth - 1, 0)), roulette);
}

void IterationMemoryParts::add(uint64_t part_bytes, const std::string& text) {
    bytes = render::add(bytes, part_bytes);  // the saturating sum above, not this member
    what += ", " + text;
}

IterationMemoryEstimate estimate_iteration_memory(const RenderSettings& settings, uint64_t width,
                                                  uint64_t height, int threads) {
    const Algorithm& algorithm = find_algorithm_or_throw(settings.algorithm);
    const uint64_t pixels = mul(width, height);
    const uint64_t thread_count =
        threads > 0 ? uint64_t(threads) : std::max(1u, std::thread::hardware_concurrency());

    IterationMemoryParts parts;
    parts.bytes = mul(thread_count, kPerThreadBytes);
    // Technique layers: a sum per layer in the renderer's result and in its iteration image.
    const uint64_t layers = TechniqueLayers::names(settings.layers).size();
    if (layers > 0)
        parts.add(mul(layers, film_memory_bytes(width, height, 2)),
                  std::to_string(layers) + " technique layers");
    algorithm.iteration_memory(IterationMemoryInput{settings, pixels, thread_count,
                                                    assumed_light_vertices_per_path(settings)},
                               parts);

    IterationMemoryEstimate e;
    e.bytes = parts.bytes;
    e.what = algorithm.name + "'s working memory per iteration (estimated " +
             format_bytes(e.bytes) + ": " + std::to_string(thread_count) +
             (thread_count == 1 ? " thread x " : " threads x ") + format_bytes(kPerThreadBytes) +
             parts.what + parts.hint + ")";
    return e;
}

void add_light_path_memory(const IterationMemoryInput& in, const LightPathStorage& storage,
                           IterationMemoryParts& parts) {
    const RenderSettings& settings = in.settings;
    const uint64_t vertices_per_path = in.light_vertices_per_path;
    const uint64_t paths = settings.light_path_count > 0 ? settings.light_path_count : in.pixels;
    uint64_t per_vertex = kLightVertexBytes;
    if (storage.merges) per_vertex += kMergeIndexBytes;
    if (storage.volume_estimators) per_vertex += kVolumeEstimatorBytes;
    if (storage.volume_estimators && settings.photon_beams && settings.short_photon_beams)
        per_vertex += kBeamReplayBytes;
    parts.add(add(mul(mul(paths, vertices_per_path), per_vertex), mul(paths, 4)),
              std::to_string(paths) + " light paths x up to " + std::to_string(vertices_per_path) +
                  " stored vertices x " + std::to_string(per_vertex) + " B");
    // bpt's J2 keeps each light path's rays in homogeneous media (iteration_storage.h's
    // LightRay: the emission ray and one per scattering vertex, up to V + 1, and the path's 4-B
    // end) and each stored vertex's J2 state in a side array (Joint2Vertex), in the chunks too.
    const bool joint2 =
        storage.joint2_possible && settings.joint_connections && settings.joint2_connections;
    const uint64_t joint2_per_path = joint2 ? add(mul(vertices_per_path + 1, kLightRayBytesBound),
                                                  mul(vertices_per_path, kJoint2VertexBytesBound))
                                            : 0;
    if (joint2) parts.add(mul(paths, add(joint2_per_path, 4)), "J2's light rays and vertex states");
    const uint64_t chunk_paths =
        std::min(paths, mul(mul(in.threads, kChunksInFlightPerThread), kLightPathsPerChunk));
    parts.add(mul(chunk_paths, add(mul(vertices_per_path, kLightVertexBytes), joint2_per_path)),
              "the light pass's chunks in flight");
    parts.hint = "; fewer light paths (--light-paths) or a lower --max-depth need less";
}

void add_vpl_memory(const IterationMemoryInput& in, bool importance_records,
                    IterationMemoryParts& parts) {
    const RenderSettings& settings = in.settings;
    const uint64_t vpls = mul(settings.vpl_paths, in.light_vertices_per_path);
    parts.add(mul(vpls, kLightVertexBytes),
              std::to_string(settings.vpl_paths) + " VPL paths x up to " +
                  std::to_string(in.light_vertices_per_path) + " VPLs");
    if (importance_records)
        parts.add(
            mul(mul(vpls, uint64_t(std::max(settings.importance_records, 0))), sizeof(double)),
            "the VPL importance records");
}

void add_importance_cache_memory(const IterationMemoryInput& in, uint64_t cached_vertices,
                                 IterationMemoryParts& parts) {
    const uint64_t records =
        uint64_t(double(in.pixels) * std::clamp(in.settings.ic_record_density, 0.0, 1.0)) + 1;
    parts.add(mul(mul(records, cached_vertices), kImportanceTableBytes),
              std::to_string(records) + " importance records x up to " +
                  std::to_string(cached_vertices) + " light vertices");
}

}  // namespace render
