// Query beams (P-B2D) and photon beams (B-B1D) of the bidirectional family's Iteration.

#include "core/integrators/bidirectional/iteration.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <optional>

namespace render::bidirectional {

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

float Iteration::light_photon_beam_term(float photon_beam, float arrival_distance, float sigma_t,
                                        const Vec3& wo, const Vec3& d, float pdf) const {
    if (!(photon_beam > 0)) return 0.0f;
    return mis_.photon_beam_light_term(length(cross(wo, d)), pdf, arrival_distance, sigma_t);
}

namespace {

// Whether walking an eye segment's pieces can change anything but the ray count: it draws random
// numbers only for a grid medium's transmittance (ratio tracking); homogeneous ones draw none.
bool walk_draws_numbers(const Scene& scene) {
    for (const auto& medium : scene.media())
        if (!medium->is_homogeneous()) return true;
    return false;
}

// Whether the line of `ray` (from t_min on) passes through `box`.
bool line_reaches(const Ray& ray, const Aabb& box) {
    if (box.empty()) return false;
    float t0 = ray.t_min, t1 = kInfinity;
    for (int a = 0; a < 3; ++a) {
        const float lo = box.lo[a], hi = box.hi[a];
        if (ray.direction[a] == 0.0f) {
            if (ray.origin[a] < lo || ray.origin[a] > hi) return false;
            continue;
        }
        float n = (lo - ray.origin[a]) / ray.direction[a];
        float f = (hi - ray.origin[a]) / ray.direction[a];
        if (n > f) std::swap(n, f);
        t0 = std::max(t0, n);
        t1 = std::min(t1, f);
    }
    return t0 <= t1;
}

}  // namespace

std::optional<Aabb> Iteration::gather_reach(bool points, bool beams) const {
    if (walk_draws_numbers(scene_)) return std::nullopt;  // the walk's draws are in the image
    Aabb box;
    if (points) box.expand(storage_.beam_lookup->bounds());
    if (beams)
        box.expand(storage_.photon_beams_in_grid ? storage_.photon_beam_grid.bounds()
                                                 : storage_.photon_beam_lookup->bounds());
    if (box.empty()) return box;
    // The crossings' ray offsets (Scene::spawn_ray: 1e-5 R + 1e-6 |p| each), over every
    // crossing the walk may make, with a factor 2 to spare.
    const Aabb& scene_box = scene_.bounds();
    const float extent =
        std::max({std::abs(scene_box.lo.x), std::abs(scene_box.lo.y), std::abs(scene_box.lo.z),
                  std::abs(scene_box.hi.x), std::abs(scene_box.hi.y), std::abs(scene_box.hi.z)});
    const Vec3 margin(2.0f * float(kMaxNullCrossings + 1) *
                      (1e-5f * scene_.bounding_sphere().radius + 1e-6f * extent));
    return Aabb{box.lo - margin, box.hi + margin};
}

Rgb Iteration::query_beams(const Ray& ray, const SubpathState& state, Rng& rng, RenderStats& stats,
                           TracedPieces* traced) const {
    Rgb sum(0.0f);
    if (medium_positions_.empty()) return sum;
    for_each_eye_medium_piece(ray, state, rng, stats, gather_reach(true, false), traced,
                              [&](const Medium* medium, const Ray& piece, float t_end,
                                  const SegmentDensityBuilder& before, const Rgb& transmittance) {
                                  query_beams_in_piece(ray, state, medium, piece, t_end, before,
                                                       transmittance, rng, sum);
                              });
    return sum * plan_.beam_normalization;
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
        if (lv.medium() != medium) return;  // a photon of another medium
        if (lv.path_length + state.path_length > plan_.max_length) return;
        const Vec3 x = piece.at(t);
        const float p = lv.phase()->p(-ray.direction, lv.wo);
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
             .photon_beam = light_photon_beam_term(lv, lv.wo, ray.direction, 1.0f)});
        // sigma_s at x scatters the eye's light; the photon's throughput carries its
        // own vertex's sigma_s (its distance sampling), divided out.
        Rgb photon = lv.throughput;
        if (!homogeneous) {
            const Rgb sigma_query = medium->sigma_s(x);
            const Rgb sigma_photon = medium->sigma_s(lv.p);
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
                                          RenderStats& stats, const std::optional<Aabb>& reach,
                                          TracedPieces* traced, Visit&& visit) const {
    SegmentDensityBuilder before(state.in_medium);
    Rgb transmittance(1.0f);
    const Medium* medium = state.medium;
    Ray piece = ray;
    for (int crossing = 0; crossing <= kMaxNullCrossings; ++crossing) {
        // The rest of the walk can find nothing and changes nothing: not walked.
        if (reach && !line_reaches(piece, *reach)) break;
        SurfaceInteraction si;
        ++stats.rays;
        const bool hit = scene_.intersect(piece, si);
        if (traced) traced->record(crossing, hit, si);
        const float t_end = hit ? si.t : kInfinity;
        if (medium) {
            visit(medium, piece, t_end, before, transmittance);
            transmittance *= medium->transmittance(piece, t_end, rng);
        }
        if (!hit || !si.bsdf->is_null() || transmittance.is_black()) break;
        before.add_piece(medium, piece, si.t);
        medium = medium_after_surface(si, piece.direction, medium);
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
// `replay` is the beam's replay state (null where no beam of the iteration replays: then this
// beam does not either).
Rgb beam_transmittance(const Medium* medium, const Ray& beam, float t, bool short_beams,
                       const BeamReplay* replay, Rng& rng) {
    if (short_beams && !medium->is_homogeneous())
        return medium->pass_weight_is_one()
                   ? Rgb(1.0f)
                   : medium->replay_pass_weight(beam, replay->t_max, t, replay->rng);
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
    const bool short_beams = plan_.short_photon_beams;
    PhotonBeamStaging& out = storage_.photon_beam_staging.local();
    PhotonBeam beam;
    std::optional<BeamReplay> replay;  // set where the beam replays its walk
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
        if (replay || !out.replays.empty()) {
            out.replays.resize(out.beams.size());
            out.replays.push_back(replay.value_or(BeamReplay{}));
        }
        out.beams.push_back(beam);
    };
    const Medium* medium = from.medium;
    // One piece that ends where the sample ended (short beams, or any beam ending at a
    // surface): the segment already traced it.
    if (seg.one_piece && seg.end != SegmentEnd::Escaped &&
        (short_beams || seg.end == SegmentEnd::Surface)) {
        if (!medium) return;
        if (replays_walk(medium)) {
            if (!seg.first_piece_rng) return;
            replay = BeamReplay{*seg.first_piece_rng, seg.first_piece_t_max};
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
                replay = BeamReplay{*seg.first_piece_rng, seg.first_piece_t_max};
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
        medium = medium_after_surface(si, r.direction, medium);
        r = scene_.spawn_ray(si.p, si.geometric_normal, r.direction);
    }
}

void Iteration::build_photon_beams() {
    std::vector<PhotonBeam>& beams = storage_.photon_beams;
    std::vector<BeamReplay>& replays = storage_.photon_beam_replays;
    beams.clear();
    replays.clear();
    bool replaying = false;
    for (const PhotonBeamStaging& staged : storage_.photon_beam_staging)
        replaying = replaying || !staged.replays.empty();
    for (PhotonBeamStaging& staged : storage_.photon_beam_staging) {
        if (replaying) {
            staged.replays.resize(staged.beams.size());
            replays.insert(replays.end(), staged.replays.begin(), staged.replays.end());
        }
        beams.insert(beams.end(), staged.beams.begin(), staged.beams.end());
        staged.beams.clear();
        staged.replays.clear();
    }
    // In order (the orders are distinct: any sort gives the same sequence), the replay states
    // with their beams.
    if (!replaying) {
        std::sort(beams.begin(), beams.end(),
                  [](const PhotonBeam& a, const PhotonBeam& b) { return a.order < b.order; });
    } else {
        std::vector<uint32_t> from(beams.size());  // the beam that goes to place k
        std::iota(from.begin(), from.end(), 0u);
        std::sort(from.begin(), from.end(),
                  [&](uint32_t a, uint32_t b) { return beams[a].order < beams[b].order; });
        // Each cycle of the permutation in turn, moving the records along it.
        for (uint32_t k = 0; k < from.size(); ++k) {
            if (from[k] == k) continue;
            PhotonBeam beam = beams[k];
            const BeamReplay replay = replays[k];
            uint32_t place = k;
            while (from[place] != k) {
                const uint32_t next = from[place];
                beams[place] = beams[next];
                replays[place] = replays[next];
                from[place] = place;
                place = next;
            }
            beams[place] = beam;
            replays[place] = replay;
            from[place] = place;
        }
    }
    std::vector<BeamLine>& lines = storage_.photon_beam_lines;
    lines.clear();
    lines.reserve(beams.size());
    for (const PhotonBeam& b : beams) lines.push_back(b.line);
    const float r = float(plan_.photon_beam_radius);
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

Rgb Iteration::photon_beams(const Ray& ray, const SubpathState& state, Rng& rng, RenderStats& stats,
                            TracedPieces* traced) const {
    Rgb sum(0.0f);
    if (storage_.photon_beams.empty()) return sum;
    for_each_eye_medium_piece(ray, state, rng, stats, gather_reach(false, true), traced,
                              [&](const Medium* medium, const Ray& piece, float t_end,
                                  const SegmentDensityBuilder& before, const Rgb& transmittance) {
                                  photon_beams_in_piece(ray, state, medium, piece, t_end, before,
                                                        transmittance, rng, sum);
                              });
    return sum * plan_.photon_beam_normalization;
}

void Iteration::both_beams(const Ray& ray, const SubpathState& state, Rng& rng, RenderStats& stats,
                           Rgb& query_sum, Rgb& photon_sum, TracedPieces* traced) const {
    query_sum = photon_sum = Rgb(0.0f);
    const bool points = !medium_positions_.empty(), beams = !storage_.photon_beams.empty();
    if (!points && !beams) return;
    for_each_eye_medium_piece(ray, state, rng, stats, gather_reach(points, beams), traced,
                              [&](const Medium* medium, const Ray& piece, float t_end,
                                  const SegmentDensityBuilder& before, const Rgb& transmittance) {
                                  if (points)
                                      query_beams_in_piece(ray, state, medium, piece, t_end, before,
                                                           transmittance, rng, query_sum);
                                  if (beams)
                                      photon_beams_in_piece(ray, state, medium, piece, t_end,
                                                            before, transmittance, rng, photon_sum);
                              });
    query_sum = query_sum * plan_.beam_normalization;
    photon_sum = photon_sum * plan_.photon_beam_normalization;
}

void Iteration::photon_beams_in_piece(const Ray& ray, const SubpathState& state,
                                      const Medium* medium, const Ray& piece, float t_end,
                                      const SegmentDensityBuilder& before, const Rgb& transmittance,
                                      Rng& rng, Rgb& sum) const {
    const std::vector<PhotonBeam>& beams = storage_.photon_beams;
    const bool short_beams = plan_.short_photon_beams;
    {
        Ray query = piece;
        query.t_max = t_end;
        auto gather = [&](uint32_t i, const BeamApproach& a) {
            const PhotonBeam& b = beams[i];
            if (b.medium != medium) return;  // a beam of another medium
            if (b.path_length + state.path_length > plan_.max_length) return;
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
            const Rgb beam_tr = beam_transmittance(
                medium, beam_ray, a.t_beam, short_beams,
                storage_.photon_beam_replays.empty() ? nullptr : &storage_.photon_beam_replays[i],
                rng);
            const Rgb tr = transmittance * medium->transmittance(piece, a.t_ray, rng);
            sum += tr * beam_tr * b.weight * medium->sigma_s(x) * (p * (weight / a.sin_theta));
        };
        if (storage_.photon_beams_in_grid)
            storage_.photon_beam_grid.for_each_near(query, gather);
        else
            storage_.photon_beam_lookup->for_each_near(query, gather);
    }
}

}  // namespace render::bidirectional
