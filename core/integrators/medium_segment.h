#pragma once

// Segments of bidirectional subpaths through participating media. A segment joins two
// scattering vertices; on its way it may cross index-matched (null) boundaries, so it is made
// of pieces, each in one medium or in vacuum. Bidirectional MIS needs the density of
// distance sampling along the whole segment in both directions:
//   toward_end   = P_pass of every piece but the last, times the last piece's density of a
//                  scattering event at its end (medium vertex) or its P_pass (surface),
//   toward_start = the same from the other end.
// Densities come from Medium::pdf_scatter_l and probability_pass, which are exact for
// homogeneous media; that is why the bidirectional family accepts homogeneous media only.

#include <cstdint>
#include <optional>

#include "core/base/interaction.h"
#include "core/base/render_stats.h"
#include "core/math/ray.h"
#include "core/sampling/rng.h"

namespace render {

class Medium;
class Scene;

// Index-matched boundaries crossed in one segment before a path gives up: stacks of coincident
// null surfaces would otherwise loop forever.
inline constexpr int kMaxNullCrossings = 256;

struct SegmentDensities {
    float toward_end = 1;
    float toward_start = 1;
    // Every piece is in vacuum or a homogeneous medium: the segment can carry a photon beam
    // (upbp's B-B1D is built in homogeneous media only).
    bool homogeneous = true;
    // A *short* photon beam along the segment knows its weight: every piece is in vacuum, a
    // homogeneous medium or one whose pass weight is one (Medium::pass_weight_is_one:
    // transmittance over pass probability exact, or 1), or the segment is one piece in a
    // chromatic grid (the sampling walk's pass weight replayed, Medium::replay_pass_weight).
    // The same read from either end. Long beams need none of it (ratio tracking).
    bool short_beam_support = true;
};

// Accumulates the densities of a segment piece by piece.
class SegmentDensityBuilder {
  public:
    explicit SegmentDensityBuilder(bool start_in_medium) : start_in_medium_(start_in_medium) {}
    // A piece of `length` along `ray` in `medium` (null: vacuum).
    void add_piece(const Medium* medium, const Ray& ray, float length);
    SegmentDensities finish(bool end_in_medium) const;
    int pieces() const { return pieces_; }
    bool homogeneous() const { return homogeneous_; }
    bool short_beam_support() const { return !chromatic_grid_ || pieces_ == 1; }

  private:
    bool start_in_medium_;
    int pieces_ = 0;
    float pass_before_last_ = 1;    // product of P_pass over all pieces but the last
    float pass_after_first_ = 1;    // product of P_pass over all pieces but the first
    float first_start_factor_ = 1;  // the first piece's density toward the segment's start
    float last_pass_ = 1, last_scatter_ = 1;
    bool homogeneous_ = true;
    bool chromatic_grid_ = false;  // a piece is in a chromatic grid
};

// Where a sampled segment ended.
enum class SegmentEnd { Surface, Medium, Escaped };

struct SampledSegment {
    SegmentEnd end = SegmentEnd::Escaped;
    SurfaceInteraction si;           // the surface hit (end == Surface)
    Vec3 position;                   // the vertex (surface hit or medium scattering point)
    const Medium* medium = nullptr;  // the medium the segment ended in
    Rgb weight{1.0f};                // product of the pieces' distance-sampling weights
    // end == Medium: `weight` with the last piece's sigma_s left out (MediumSample::
    // source_weight), for the collision estimator of emission at the vertex.
    Rgb source_weight{0.0f};
    SegmentDensities densities;
    float distance = 0;      // from the ray's origin to the vertex
    bool one_piece = false;  // no boundary crossed on the way (joint connections need it)
    // A null boundary on the way was reached against its declaration (medium_interface.h).
    bool against_declaration = false;
    // The first piece in a medium whose pass weight is neither one nor in closed form (a
    // chromatic grid): the random state its walk started with and its end, so that a short
    // photon beam along it can replay the walk (Medium::replay_pass_weight).
    std::optional<Rng> first_piece_rng;
    float first_piece_t_max = 0;
};

// The closest hits of the first pieces of a segment, traced already by a walk along the same
// ray through the same null boundaries (the eye pass's gathers of query and photon beams walk
// the whole segment just before it is sampled): sample_segment reads them instead of tracing
// the same rays again. Hit k is the closest hit of the ray after k crossings.
struct TracedPieces {
    static constexpr int kCapacity = 4;
    int count = 0;
    bool hit[kCapacity] = {};
    SurfaceInteraction si[kCapacity];

    // Records the closest hit of the walk's piece after `crossing` crossings (pieces past the
    // capacity, or after a gap, are traced again).
    void record(int crossing, bool was_hit, const SurfaceInteraction& interaction) {
        if (crossing != count || count >= kCapacity) return;
        hit[count] = was_hit;
        if (was_hit) si[count] = interaction;
        ++count;
    }
};

// Traces `ray` from a vertex (in a medium when `start_in_medium`) through null boundaries and
// media, sampling distances, to the next scattering vertex: a non-null surface, a scattering
// event in a medium, or nothing. Counts traced rays in `stats`. `traced`: the closest hits of
// the first pieces along this very ray, when a walk found them already (the same hits this
// function would trace: the result is the same).
SampledSegment sample_segment(const Scene& scene, Ray ray, const Medium* medium,
                              bool start_in_medium, Rng& rng, RenderStats& stats,
                              const TracedPieces* traced = nullptr);

struct SegmentConnection {
    Rgb transmittance{0.0f};  // zero when a non-null surface blocks the segment
    SegmentDensities densities;
    bool one_piece = false;  // no null boundary crossed
    // A null boundary on the way was reached against its declaration (medium_interface.h).
    bool against_declaration = false;
    const Medium* end_medium = nullptr;  // the medium the segment ends in
};

// The deterministic segment between two vertices: `ray` as Scene::spawn_ray_to builds it
// (t_max infinite toward an infinite light), starting in `medium`.
SegmentConnection connect_segment(const Scene& scene, const Ray& ray, const Medium* medium,
                                  bool start_in_medium, bool end_in_medium, Rng& rng,
                                  RenderStats& stats);

}  // namespace render
