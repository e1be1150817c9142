#pragma once

// The subpaths of the bidirectional family: the state of a subpath being extended, its vertices
// (on a surface or in a medium), the stored light vertices, and the small records that
// connections pass around. Shared by every pass of the iteration (iteration.h).

#include <cstddef>
#include <new>
#include <optional>
#include <utility>

#include "core/integrators/bidirectional/record_bounds.h"
#include "core/integrators/bidirectional/vcm_mis.h"
#include "core/integrators/medium_segment.h"
#include "core/materials/surface_bsdf.h"
#include "core/math/ray.h"
#include "core/media/medium.h"
#include "core/media/medium_interface.h"
#include "core/media/phase_function.h"
#include "core/sampling/half_line_equiangular.h"

namespace render::bidirectional {

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
// measure is volume instead of area (core/integrators/bidirectional/vcm_mis.h).
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
    // f alone, for a technique that needs no densities (a VPL connection has no MIS weight).
    Rgb f(const Vec3& wo, const Vec3& wi) const {
        return phase ? Rgb(phase->p(wo, wi)) : bsdf->f(wo, wi);
    }
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
    // A medium vertex, or a surface that declares no medium: a path has the same medium on
    // both sides of it, whichever way it goes through.
    bool keeps_medium() const { return phase || !is_medium_transition(*shape); }
    // The medium toward direction d of a path that arrived in `medium` (medium_interface.h).
    const Medium* medium_toward(const Vec3& d) const {
        if (phase) return medium;
        return medium_after_surface(*shape, n, d, medium);
    }
};

// Joint (J2) connections' state of a subpath vertex, which resample a light vertex on the light
// path's ray that reached it (docs/design/media.md): the position `previous` was reached from; this
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

// What only a medium light vertex stores; a surface vertex has its BSDF in its place
// (LightVertex). previous, arrival_distance, sigma_t and photon_beam are Vertex's: only J1
// (previous) and photon beams (the others) read them, and only at medium vertices.
struct MediumLightVertex {
    const Medium* medium = nullptr;
    const PhaseFunction* phase = nullptr;
    Vec3 previous;
    float arrival_distance = 0;
    float sigma_t = 0;
    float photon_beam = 0;
};

// A stored light-subpath vertex with a non-delta BSDF or in a medium: 128 bytes, two cache lines
// (SmallVCM's is 120; a whole Vertex inside made it 192, three lines). What a merge reads
// (path_length, wo, mis, throughput; in a medium the medium and p) lies in the first line; a
// connection reads the BSDF, which ends the second. A surface vertex's BSDF and a medium
// vertex's MediumLightVertex share their bytes, as the two never both exist; the geometric
// normal is the BSDF's, the phase function and medium the medium part's. A surface light
// vertex's arrival medium is kept beside it only where merges compare it with the eye's
// (IterationStorage::light_vertex_media); nothing reads its shape, nor a light vertex's
// joint_distance_pdf or query_beam (eye-vertex quantities), so they are not stored. Built from
// the Vertex a light subpath reached.
struct alignas(64) LightVertex {
    Vec3 p;
    Vec3 wo;  // toward the previous vertex of the light subpath
    Rgb throughput;
    MisQuantities mis;
    int path_length = 0;
    bool finite_light = true;  // the subpath starts at a point (J1 at s = 1 needs one)

    LightVertex() : bsdf_() {}
    LightVertex(const Vertex& v, const Vec3& wo_, const Rgb& throughput_, int path_length_,
                const MisQuantities& mis_, bool finite_light_)
        : p(v.p),
          wo(wo_),
          throughput(throughput_),
          mis(mis_),
          path_length(path_length_),
          finite_light(finite_light_),
          in_medium_(v.in_medium()) {
        if (in_medium_)
            new (&medium_) MediumLightVertex{.medium = v.medium,
                                             .phase = v.phase,
                                             .previous = v.previous,
                                             .arrival_distance = v.arrival_distance,
                                             .sigma_t = v.sigma_t,
                                             .photon_beam = v.photon_beam};
        else
            new (&bsdf_) OptionalSurfaceBsdf(v.bsdf);
    }
    LightVertex(const LightVertex& o) : LightVertex() { assign(o); }
    LightVertex(LightVertex&& o) noexcept : LightVertex() { assign(std::move(o)); }
    LightVertex& operator=(const LightVertex& o) {
        if (this != &o) assign(o);
        return *this;
    }
    LightVertex& operator=(LightVertex&& o) noexcept {
        if (this != &o) assign(std::move(o));
        return *this;
    }
    ~LightVertex() { destroy_part(); }

    bool in_medium() const { return in_medium_; }
    // A medium vertex's medium (null at a surface).
    const Medium* medium() const { return in_medium_ ? medium_.medium : nullptr; }
    const PhaseFunction* phase() const { return in_medium_ ? medium_.phase : nullptr; }
    // J1's and photon beams' quantities of a medium vertex (Vertex); a surface vertex's are 0,
    // which no technique reads but as "none".
    Vec3 previous() const { return in_medium_ ? medium_.previous : Vec3(); }
    float arrival_distance() const { return in_medium_ ? medium_.arrival_distance : 0.0f; }
    float sigma_t() const { return in_medium_ ? medium_.sigma_t : 0.0f; }
    float photon_beam() const { return in_medium_ ? medium_.photon_beam : 0.0f; }
    // A surface vertex's BSDF (empty in a medium).
    std::optional<SurfaceBsdf> bsdf() const {
        return in_medium_ ? std::nullopt : std::optional<SurfaceBsdf>(*bsdf_);
    }
    // As Vertex's: the geometric normal (zero in a medium), the cosines, f and the densities.
    Vec3 n() const { return in_medium_ ? Vec3() : bsdf_->geometric_normal(); }
    float cos(const Vec3& w) const {
        return in_medium_ ? 1.0f : abs_dot(bsdf_->geometric_normal(), w);
    }
    float shading_cos(const Vec3& w) const { return in_medium_ ? 1.0f : bsdf_->abs_cos_shading(w); }
    Rgb f(const Vec3& wo_, const Vec3& wi) const {
        return in_medium_ ? Rgb(medium_.phase->p(wo_, wi)) : bsdf_->f(wo_, wi);
    }
    BsdfEvaluation evaluate(const Vec3& wo_, const Vec3& wi) const {
        if (!in_medium_) return bsdf_->evaluate(wo_, wi);
        const float pdf = medium_.phase->p(wo_, wi);  // as Vertex::evaluate
        return BsdfEvaluation{Rgb(pdf), BsdfPdf{pdf, pdf}};
    }

  private:
    void destroy_part() {
        if (!in_medium_) bsdf_.~OptionalSurfaceBsdf();
    }
    // The other's fields and part (its BSDF moved where it is an rvalue: no reference count).
    template <class Other>
    void assign(Other&& o) {
        destroy_part();
        p = o.p;
        wo = o.wo;
        throughput = o.throughput;
        mis = o.mis;
        path_length = o.path_length;
        finite_light = o.finite_light;
        in_medium_ = o.in_medium_;
        if (in_medium_)
            new (&medium_) MediumLightVertex(o.medium_);
        else
            new (&bsdf_) OptionalSurfaceBsdf(std::forward<Other>(o).bsdf_);
    }

    bool in_medium_ = false;
    union {
        OptionalSurfaceBsdf bsdf_;
        MediumLightVertex medium_;
    };
};
static_assert(sizeof(Joint2Vertex) <= kJoint2VertexBytesBound,
              "Joint2Vertex grew: raise kJoint2VertexBytesBound (the memory estimate uses it)");
static_assert(sizeof(LightVertex) <= kLightVertexBytesBound,
              "LightVertex grew: raise kLightVertexBytesBound (the memory estimate uses it)");
static_assert(sizeof(LightVertex) == 128, "a stored light vertex is two cache lines");

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
    // Traced: a null boundary on the way was reached against its declaration, and the medium
    // the link ends in (medium_interface.h).
    bool against_declaration = false;
    const Medium* end_medium = nullptr;
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

// The geometry of connecting eye vertex v (reached from wo) to a light vertex: the unit
// direction toward the light vertex, the squared distance, and both vertices' BSDF (or phase)
// evaluations along it. Empty when the vertices coincide or either side reflects nothing.
struct ConnectionGeometry {
    Vec3 d;
    float dist2;
    BsdfEvaluation eye, light;
};

}  // namespace render::bidirectional
