#pragma once

// An emitting medium as a light of the bidirectional family (docs/design/media.md, "Emitting media
// as lights"): light subpaths start at points y_0 of the medium, next-event estimation samples such
// points, and the eye's collision estimator weighs the emission it finds against both.
//
// The region is the medium's bounding box B: the union of the bounds of the shapes that have the
// medium on either side. A medium is entered only across those shapes, so it counts as bounded
// unless the camera sits in it outside B (or no shape declares it); otherwise it is unbounded and
// refused. Open surfaces that declare it (a rectangle) are not detected. Points are drawn from
// a piecewise-constant density over a lattice of cells of B,
//     p_V(x) = P(cell of x) / |cell|,   P(c) proportional to 1/2 mean_w + 1/2 w_c,
// where w_c estimates the luminance of sigma_a L_e over cell c at load (a fixed-seed average of a
// few points). The uniform half keeps p_V positive wherever the integrand is, so
// sigma_a L_e / p_V is unbiased whatever the estimates; the density is exact. A homogeneous
// medium has one cell: p_V = 1 / |B|. A point of B that is not in the medium (outside the
// bounding shapes) carries no emission: the sample is wasted, never biased. Emission is
// isotropic: a direction has density 1 / 4 pi.
//
// Whether a point is in the medium depends on the path through it (Mitsuba's rule: the medium is
// set by the last declaring interface crossed, docs/design/media.md "Which medium a path is in"):
// in nested shapes that name an interior and no exterior, the region between them is in the
// medium for a path that entered the outer shape and in vacuum for one that left the inner one.
// So the sampler gives sigma_a L_e as if the point were in the medium, and the techniques decide
// with the path (source_seen_from): next-event estimation from the receiver's side, a light
// subpath's start along its own first direction (source_leaving).

#include <memory>
#include <string>
#include <vector>

#include "core/base/shape.h"
#include "core/lights/light.h"
#include "core/sampling/distribution.h"

namespace render {

class Scene;

// A point of the emitter: its position, the source sigma_a L_e there (zero outside the medium)
// and p_V.
struct VolumePointSample {
    Vec3 p;
    Rgb source;
    float pdf_volume = 0;
};

class VolumeEmitter final : public Light {
  public:
    // `scene` must be committed (its geometry answers which medium a point is in) and outlive
    // the emitter; `box` is the medium's region (volume_emitter_region).
    VolumeEmitter(const Scene& scene, const Medium& medium, const Aabb& box, std::string name);

    // Three uniform numbers to a point with density p_V; its source is source_in_medium (the
    // caller decides with the path whether the point is in the medium: source_seen_from).
    VolumePointSample sample_point(const Vec3& u) const;
    // p_V(p), for a point of the medium.
    float pdf_volume(const Vec3& p) const;
    // sigma_a(p) L_e(p) where a probe ray finds the medium, else zero.
    Rgb source(const Vec3& p) const;
    // sigma_a(p) L_e(p) if a path that goes from p along d (unit) and is in `medium_there` at
    // `distance` is in this medium at p (medium_seen_from), else zero.
    Rgb source_seen_from(const Vec3& p, const Vec3& d, float distance,
                         const Medium* medium_there) const;
    // sigma_a(p) L_e(p) for a light subpath that starts at p along d (unit), if it is in this
    // medium there: the side facing p of the first surface along d when that surface declares a
    // medium (the camera's path would cross it last before p). When it declares none the
    // subpath scatters or passes there with a medium this cannot know, and the probe decides
    // (source): a floor that coincides with the medium's boundary must not hide the boundary.
    Rgb source_leaving(const Vec3& p, const Vec3& d) const;
    // sigma_a(p) L_e(p) for a point known to be in the medium (a path's vertex there): no probe.
    Rgb source_in_medium(const Vec3& p) const;
    // Whether p lies in this medium (a probe ray: the side of the first surface it hits).
    bool contains(const Vec3& p) const;
    const Aabb& box() const { return box_; }
    const std::string& name() const { return name_; }

    // Light's interface. illuminate() and emit() take two numbers and a volume needs three:
    // the bidirectional family calls sample_point instead (volume_emitter_sampling.h); these
    // report no sample, and no ray hits a volume emitter.
    bool illuminate(const Vec3&, Vec2, LightIlluminateSample&) const override { return false; }
    bool emit(Vec2, Vec2, LightEmitSample&) const override { return false; }
    LightRadiance radiance(const Vec3&, const Vec3&, const Vec3&) const override { return {}; }
    // 4 pi integral of sigma_a L_e (estimated at load; it only shapes the light selection).
    Rgb power() const override { return power_; }
    bool is_delta() const override { return false; }
    bool is_finite() const override { return true; }
    const VolumeEmitter* as_volume() const override { return this; }
    std::string to_string() const override;

  private:
    int cell_index(const Vec3& p) const;

    const Scene& scene_;
    const Medium& emitting_medium_;
    Aabb box_;
    std::string name_;
    int resolution_ = 1;  // cells per axis
    Vec3 cell_size_;
    float cell_volume_ = 0;
    Distribution1D cells_;
    Rgb power_;
};

// The region of an emitting medium for VolumeEmitter, or an empty box with `why` set when it has
// none that is finite (no shape declares it, or the camera is in it outside them).
Aabb volume_emitter_region(const Scene& scene, const Medium* medium, std::string& why);

// Whether point p is in `medium`: a probe ray from p, the side of the first surface it meets
// that declares a medium. Exact where the scene's declarations agree; where they do not, the
// answer depends on the path (medium_seen_from).
bool point_in_medium(const Scene& scene, const Vec3& p, const Medium* medium);

// The medium at p of a path one of whose segments joins p to p + distance d (d unit; distance
// may be infinite), being in `medium_there` at the far end: Mitsuba's rule read backwards, the
// side facing p of the first surface between them that declares a medium, or `medium_there`
// when none does. Surfaces that declare none are passed (the path's medium does not change
// there). Nested shapes naming an interior and no exterior give different answers for
// different segments through the same point, as the rule does.
const Medium* medium_seen_from(const Scene& scene, const Vec3& p, const Vec3& d, float distance,
                               const Medium* medium_there);

}  // namespace render
