// The MIS weights of the techniques that can sample one fixed path.
//
// For explicit paths (camera, a few vertices with diffuse, glossy and mirror BSDFs or in a
// medium, and an area, point, directional or constant light) the test runs the subpath
// recursions of vcm_mis.h along the path from both ends, exactly as the integrator
// (core/integrators/bidirectional/) does while tracing, and evaluates the weight of every technique
// that can produce the path: emission hit (s = 0), next-event estimation (s = 1), every connection
// (s, t >= 2), light tracing (t = 1) and every merge at a non-specular vertex, and in fog the
// J1 joint connections (every junction with a medium vertex on the eye side, s = 1 included)
// and upbp's beams. For BPT (connections only), BPM (merges only) and VCM (both), with the power
// and the balance heuristic:
//   - the weights must sum to one: any density, cosine or distance that the recursion gets
//     wrong for some techniques and not for others breaks it;
//   - each weight must equal p_k^beta / sum_j p_j^beta, with every technique's density p_k of
//     the whole path written out directly (reference_weights, no recursion). This catches what
//     the sum cannot: a factor wrong for all techniques alike, such as the merging
//     normalisation eta of medium vertices (weights built with any eta sum to one).
//
// Paths in fog. The camera, every vertex and finite lights are inside one homogeneous medium
// with a chromatic sigma_t. A vertex is on a surface (BSDF, normal) or in the medium
// (Material::Medium: the fog's Henyey-Greenstein phase function and no normal, so cosines are 1,
// the phase value is the density in both directions, and merging there uses photon points with
// eta = 4/3 pi r^3 N instead of pi r^2 N). Sampling a segment also samples its length, so each
// segment has a distance density at either end: pdf_scatter_l(t) (per unit length) at a medium
// vertex, probability_pass(t) at a surface vertex, the light or the camera (surface-like
// endpoints), both from a real HomogeneousMedium (core/integrators/medium_segment.h). Directional
// and constant lights are outside the fog: it fills a ball around the scene with a null boundary,
// so the segment toward such a light crosses the fog only up to the ball (the vacuum beyond is
// passed with probability one), and its densities are those of that length.

#include "core/integrators/bidirectional/vcm_mis.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <optional>
#include <tuple>
#include <vector>

#include "core/camera/perspective_camera.h"
#include "core/integrators/joint_segment.h"
#include "core/integrators/medium_segment.h"
#include "core/integrators/volume_light_sampling.h"
#include "core/lights/area_light.h"
#include "core/lights/constant_light.h"
#include "core/lights/directional_light.h"
#include "core/lights/point_light.h"
#include "core/materials/conductor.h"
#include "core/materials/diffuse.h"
#include "core/materials/phong.h"
#include "core/materials/surface_bsdf.h"
#include "core/math/constants.h"
#include "core/media/constant_volume.h"
#include "core/media/grid_volume.h"
#include "core/media/henyey_greenstein.h"
#include "core/media/heterogeneous_medium.h"
#include "core/media/homogeneous_medium.h"
#include "core/sampling/half_line_equiangular.h"
#include "core/sampling/joint_light_distance.h"
#include "core/sampling/rng.h"
#include "core/sampling/warp.h"
#include "core/shapes/triangle_mesh.h"

namespace render {
namespace {

// Volume: a point y of an emitting medium filling the fog (a volume light, docs/design/media.md
// "Emitting media as lights"): a medium endpoint, reached by the eye by a scattering event.
enum class LightKind { Area, Point, Directional, Constant, Volume };
enum class Material { Diffuse, Glossy, Mirror, Medium };

struct PathVertex {
    Vec3 p;
    Vec3 n;                                // zero in the medium
    const Bsdf* bsdf = nullptr;            // surface vertices
    const PhaseFunction* phase = nullptr;  // medium vertices
    bool specular = false;

    bool in_medium() const { return phase != nullptr; }
    // |cos| as the densities use it: 1 in the medium (subpath.h, Vertex::cos).
    float cos(const Vec3& w) const { return phase ? 1.0f : abs_dot(n, w); }
};

// Densities of the light end of a path, as the light reports them (selection probability 1).
struct LightEnd {
    bool delta = false;
    bool finite = true;
    float direct_pdf_a = 0;    // illuminate()'s density of the endpoint (area; solid angle if
                               // infinite)
    float emission_pdf_w = 0;  // emit()'s density of (endpoint, direction)
    float direct_pdf_w = 0;    // illuminate()'s solid-angle density at the first vertex
    float cos_light = 1;
    bool volume = false;  // a volume light's point: a medium endpoint (cos 1, volume measure)
};

enum class TechniqueKind {
    Emission,
    Direct,
    Connection,
    Camera,
    Merge,
    JointConnection,
    JointDirect,
    Joint2Connection,
    QueryBeam,
    PhotonBeam
};
struct Technique {
    TechniqueKind kind;
    // Connection: light vertex `vertex` to eye vertex `vertex + 1`; Merge: the vertex merged at;
    // JointConnection: as Connection, with the eye vertex (in the medium) sampled by half-line
    // equi-angular sampling toward the light vertex instead of by distance sampling (J1);
    // JointDirect: J1 at s = 1, next-event estimation with vertex 0 (in the medium) sampled
    // toward the light point;
    // Joint2Connection: as JointConnection, with the light vertex (in the medium) sampled on the
    // light ray from its predecessor by B2 instead of by distance sampling (J2);
    // QueryBeam: the medium vertex `vertex` is a photon gathered along the camera segment
    // that reaches it (P-B2D, the long query beam: the eye side samples no distance there);
    // PhotonBeam: the medium vertex `vertex` is the closest approach of the light segment that
    // reaches it (the photon beam) and the camera segment that reaches it (the query), B-B1D:
    // neither side samples the distance there.
    size_t vertex = 0;
};

// The recursive quantities of both subpaths along the path, as the integrator holds them.
struct SubpathStates {
    std::vector<MisQuantities> light;         // after arriving at each vertex
    std::vector<MisQuantities> eye;           // after arriving at each vertex
    std::vector<MisQuantities> eye_before;    // before arriving at each vertex (query beams)
    std::vector<MisQuantities> light_before;  // before arriving at each vertex (photon beams)
    // The terms each subpath carried into its arrival at each vertex (photon beams).
    std::vector<float> light_carried_query, light_carried_photon, eye_carried_photon;
    MisQuantities eye_at_light;  // after hitting the light or leaving the scene
};

class MisSumTest : public ::testing::Test {
  protected:
    static constexpr int kWidth = 64, kHeight = 64;
    static constexpr double kLightPaths = double(kWidth * kHeight);
    static constexpr float kFogRadius = 14.0f;  // the fog's ball, centred at the origin
    // Endpoint ids for segments: vertex indices, kLightEnd, and vertices_.size() for the camera.
    static constexpr int kLightEnd = -1;

    MisSumTest()
        : diffuse_(Rgb(0.6f)),
          glossy_(Rgb(0.2f), Rgb(0.6f), 20.0f),
          mirror_(std::nullopt, Rgb(1.0f)),
          rectangle_(make_rectangle_mesh(), Transform::scale(Vec3(0.3f, 0.2f, 1.0f)), false, false,
                     "light"),
          // Chromatic: the three channels' distance densities differ, and the medium's
          // densities are their averages (spectral MIS, core/media/medium.h).
          fog_medium_(Rgb(0.06f, 0.16f, 0.3f), Rgb(0.24f, 0.64f, 1.2f),
                      std::make_shared<HenyeyGreenstein>(0.4f)) {}

    const Bsdf* bsdf_for(Material m) const {
        switch (m) {
            case Material::Diffuse:
                return &diffuse_;
            case Material::Glossy:
                return &glossy_;
            default:
                return &mirror_;
        }
    }

    // Builds a path from the camera through the given materials to a light of the given kind,
    // in vacuum or (in_fog) in the fog. Returns false (skip) when a random choice made the
    // geometry degenerate.
    bool build_path(Rng& rng, const std::vector<Material>& materials, LightKind kind,
                    bool in_fog = false) {
        fog_ = in_fog ? (grid_fog_ ? grid_fog_ : &fog_medium_) : nullptr;
        const Vec3 eye(0.1f, -0.2f, -3.0f), target(0, 0, 0);
        camera_ = PerspectiveCamera(Transform::look_at(eye, target, Vec3(0, 1, 0)), 50.0f, 'x',
                                    kWidth, kHeight);
        // Interior vertices are built in eye order and reversed at the end.
        std::vector<PathVertex> eye_order;
        Vec3 position = eye;
        Vec3 direction = camera_
                             .generate_ray(Vec2(rng.next_1d() * kWidth * 0.8f + 6,
                                                rng.next_1d() * kHeight * 0.8f + 6))
                             .direction;
        for (Material m : materials) {
            position = position + direction * (0.7f + rng.next_1d());
            if (m == Material::Medium) {
                // Scattering in the fog: any direction (the phase function has full support).
                eye_order.push_back(
                    PathVertex{position, Vec3(0.0f), nullptr, &fog_medium_.phase(), false});
                direction = warp::square_to_uniform_sphere(rng.next_2d());
                continue;
            }
            Vec3 n = random_normal_facing(rng, -direction);
            eye_order.push_back(
                PathVertex{position, n, bsdf_for(m), nullptr, m == Material::Mirror});
            direction = m == Material::Mirror
                            ? reflect(-direction, n)
                            : Frame::from_normal(n).to_world(random_direction_above(rng, 0.2f));
            if (dot(direction, n) < 0.1f) return false;
        }
        vertices_.assign(eye_order.rbegin(), eye_order.rend());
        kind_ = kind;

        // The light end: `direction` points from the last vertex toward the light.
        const Vec3 first = vertices_.front().p;
        SceneSphere sphere{Vec3(0, 0, 0), 6.0f};
        end_ = LightEnd{};
        switch (kind) {
            case LightKind::Area: {
                light_point_ = first + direction * (0.8f + rng.next_1d());
                light_normal_ = random_normal_facing(rng, -direction);
                auto light = std::make_unique<AreaLight>(&rectangle_, Rgb(1.0f));
                LightRadiance le = light->radiance(light_point_, light_normal_, direction);
                const float d2 = length_squared(light_point_ - first);
                end_.delta = false;
                end_.finite = true;
                end_.cos_light = abs_dot(light_normal_, direction);
                end_.direct_pdf_a = le.pdf_direct_a;
                end_.emission_pdf_w = le.pdf_emission_w;
                end_.direct_pdf_w = le.pdf_direct_a * d2 / end_.cos_light;
                light_ = std::move(light);
                break;
            }
            case LightKind::Point: {
                light_point_ = first + direction * (0.8f + rng.next_1d());
                set_delta_light_end(std::make_unique<PointLight>(light_point_, Rgb(1.0f)), first,
                                    true);
                break;
            }
            case LightKind::Directional: {
                auto light = std::make_unique<DirectionalLight>(-direction, Rgb(1.0f));
                light->preprocess(sphere);
                set_delta_light_end(std::move(light), first, false);
                break;
            }
            case LightKind::Constant: {
                auto light = std::make_unique<ConstantLight>(Rgb(1.0f));
                light->preprocess(sphere);
                LightRadiance le = light->radiance(Vec3(), Vec3(), direction);
                end_.delta = false;
                end_.finite = false;
                end_.cos_light = 1;
                end_.direct_pdf_a = le.pdf_direct_a;  // solid angle for infinite lights
                end_.emission_pdf_w = le.pdf_emission_w;
                end_.direct_pdf_w = le.pdf_direct_a;
                light_ = std::move(light);
                break;
            }
            case LightKind::Volume: {
                // Only in fog (the emitting medium is the fog itself). The densities are those
                // next-event estimation reports (volume_light_illuminate) for any p_V: the
                // weights must sum to one whatever the light's density.
                if (!in_fog) return false;
                light_point_ = first + direction * (0.8f + rng.next_1d());
                const float pdf_volume = 0.01f + 0.5f * rng.next_1d();
                LightIlluminateSample ls;
                if (!volume_light_illuminate(first, light_point_, Rgb(1.0f), pdf_volume, ls))
                    return false;
                end_.finite = true;
                end_.volume = true;
                end_.cos_light = ls.cos_at_light;
                end_.direct_pdf_a = pdf_volume;  // selection probability 1
                end_.emission_pdf_w = ls.pdf_emission_w;
                end_.direct_pdf_w = ls.pdf_direct_w;
                light_.reset();
                break;
            }
        }
        to_light_ = direction;
        if (fog_) {
            // Everything finite must be inside the fog's ball.
            for (const PathVertex& v : vertices_)
                if (length(v.p) > kFogRadius - 0.5f) return false;
            if (end_.finite && length(light_point_) > kFogRadius - 0.5f) return false;
            // Distance from the first vertex along to_light_ to the ball's boundary.
            const float b = dot(first, to_light_);
            fog_exit_ = -b + std::sqrt(b * b - length_squared(first) + kFogRadius * kFogRadius);
        }
        return true;
    }

    // The light end of a delta light (point or directional), with the densities it reports.
    void set_delta_light_end(std::unique_ptr<Light> light, const Vec3& first, bool finite) {
        LightIlluminateSample ls;
        EXPECT_TRUE(light->illuminate(first, Vec2(0.5f, 0.5f), ls));
        LightEmitSample es;
        EXPECT_TRUE(light->emit(Vec2(0.3f, 0.3f), Vec2(0.2f, 0.7f), es));
        end_.delta = true;
        end_.finite = finite;
        end_.cos_light = 1;
        end_.direct_pdf_a = es.pdf_direct_a;
        end_.emission_pdf_w = ls.pdf_emission_w;
        end_.direct_pdf_w = ls.pdf_direct_w;
        light_ = std::move(light);
    }

    // Unit direction from vertex i toward its light-side neighbour (the light for i = 0).
    Vec3 toward_light(size_t i) const {
        if (i > 0) return normalize(vertices_[i - 1].p - vertices_[i].p);
        return end_.finite ? normalize(light_point_ - vertices_[0].p) : to_light_;
    }
    // Unit direction from vertex i toward its eye-side neighbour (the camera for the last).
    Vec3 toward_eye(size_t i) const {
        const Vec3 next = i + 1 < vertices_.size() ? vertices_[i + 1].p : camera_.position();
        return normalize(next - vertices_[i].p);
    }
    float distance2_to_light_side(size_t i) const {
        if (i > 0) return length_squared(vertices_[i - 1].p - vertices_[i].p);
        return end_.finite ? length_squared(light_point_ - vertices_[0].p) : 1.0f;
    }
    float distance2_to_eye_side(size_t i) const {
        const Vec3 next = i + 1 < vertices_.size() ? vertices_[i + 1].p : camera_.position();
        return length_squared(next - vertices_[i].p);
    }
    SurfaceBsdf surface(size_t i, TransportMode mode) const {
        const PathVertex& v = vertices_[i];
        return SurfaceBsdf(*v.bsdf, Frame::from_normal(v.n), v.n, mode);
    }
    // Vertex i's densities of scattering from wo to wi (forward) and back (reverse); a phase
    // function's value is both, in either transport mode.
    BsdfPdf pdf_at(size_t i, TransportMode mode, const Vec3& wo, const Vec3& wi) const {
        const PathVertex& v = vertices_[i];
        if (v.phase) {
            const float p = v.phase->p(wo, wi);
            return BsdfPdf{p, p};
        }
        return surface(i, mode).pdf_w(wo, wi);
    }
    float camera_pdf_w(const Vec3& dir) const {
        return camera_.direction_pdf_w(dir) * float(kWidth * kHeight);
    }

    // --- segment densities ------------------------------------------------------------------

    // An endpoint's position (for an infinite light: a point in its direction).
    Vec3 endpoint(int id) const {
        if (id == kLightEnd) return end_.finite ? light_point_ : vertices_[0].p + to_light_;
        return id == int(vertices_.size()) ? camera_.position() : vertices_[size_t(id)].p;
    }
    // Length of the fog crossed between two endpoints: the distance, or up to the fog's
    // boundary toward an infinite light.
    float fog_length(int a, int b) const {
        if (!end_.finite && (a == kLightEnd || b == kLightEnd)) return fog_exit_;
        return length(endpoint(b) - endpoint(a));
    }
    // Distance density, at endpoint `id`, of a segment reaching it after `t` in the fog.
    float distance_density(int id, const Ray& ray, float t) const {
        if (!fog_) return 1.0f;
        return medium_endpoint(id) ? fog_->pdf_scatter_l(ray, t) : fog_->probability_pass(ray, t);
    }
    // Whether endpoint `id` is reached by a scattering event: a medium vertex, or a volume
    // light's point.
    bool medium_endpoint(int id) const {
        if (id == kLightEnd) return end_.volume;
        return id >= 0 && id < int(vertices_.size()) && vertices_[size_t(id)].in_medium();
    }
    // The segment from endpoint `from` to endpoint `to`, as sample_segment / connect_segment
    // report it when traced from `from`: toward_end at `to`, toward_start at `from`.
    SegmentDensities segment(int from, int to) const {
        if (fog_ && !fog_->is_homogeneous()) return grid_segment(from, to);
        const Vec3 a = endpoint(from);
        const Ray ray(a, normalize(endpoint(to) - a));
        const float t = fog_length(from, to);
        return SegmentDensities{distance_density(to, ray, t), distance_density(from, ray, t)};
    }

    // In a grid fog the densities depend on where a piece starts and on sigma_t at both ends
    // (the midpoint-rule proxies of heterogeneous_medium.h), so the segment is built by the
    // integrator's SegmentDensityBuilder over its real pieces: toward an infinite light the fog
    // up to the ball's boundary, then vacuum.
    SegmentDensities grid_segment(int from, int to) const {
        auto medium_vertex = [&](int id) { return medium_endpoint(id); };
        const bool infinite = !end_.finite && (from == kLightEnd || to == kLightEnd);
        if (!infinite) {
            const Vec3 a = endpoint(from), b = endpoint(to);
            SegmentDensityBuilder pieces(medium_vertex(from));
            pieces.add_piece(fog_, Ray(a, normalize(b - a)), length(b - a));
            return pieces.finish(medium_vertex(to));
        }
        const Vec3 exit = vertices_[0].p + to_light_ * fog_exit_;
        if (to == kLightEnd) {
            SegmentDensityBuilder pieces(medium_vertex(from));
            pieces.add_piece(fog_, Ray(vertices_[0].p, to_light_), fog_exit_);
            pieces.add_piece(nullptr, Ray(exit, to_light_), kInfinity);
            return pieces.finish(false);
        }
        SegmentDensityBuilder pieces(false);
        pieces.add_piece(nullptr, Ray(exit + to_light_, -to_light_), kInfinity);
        pieces.add_piece(fog_, Ray(exit, -to_light_), fog_exit_);
        return pieces.finish(medium_vertex(to));
    }

    // --- joint (J1) connections ----------------------------------------------------------------

    // J1's density of the medium vertex `at` sampled on the half-line from endpoint `from`
    // through it, toward endpoint `toward` (equi-angular over the whole half-line).
    float joint_pdf(int from, int at, int toward) const {
        const Vec3 o = endpoint(from), x = endpoint(at);
        return HalfLineEquiAngularSampler(o, normalize(x - o), endpoint(toward))
            .pdf_l(length(x - o));
    }
    // Whether junction `eye_side` (its eye-side vertex; the light-side vertex is eye_side - 1)
    // has a J1 technique: the eye-side vertex is in the medium and the light-side one is a
    // scattering vertex, or (J1 at s = 1) a finite light's point.
    bool has_joint(int eye_side) const {
        const int first = joint_light_ && end_.finite ? 0 : 1;
        return joint_ && eye_side >= first && eye_side < int(vertices_.size()) &&
               vertices_[size_t(eye_side)].in_medium();
    }
    // r = p_J1 / p_connection of that junction when its eye-side vertex is sampled from `from`
    // (the next vertex toward the eye, or the camera): only the eye-side distance density
    // differs.
    float joint_ratio(int eye_side, int from) const {
        if (!has_joint(eye_side)) return 0.0f;
        return joint_pdf(from, eye_side, eye_side - 1) / segment(from, eye_side).toward_end;
    }

    // --- joint (J2) connections ----------------------------------------------------------------

    // Whether junction `eye_side` has a J2 technique: a J1 technique whose light-side vertex is
    // in the medium and was reached from a scattering vertex or a finite light's point (bpt
    // resamples it on that light ray: the emission ray at junction 1, deeper ones beyond).
    bool has_joint2(int eye_side) const {
        return joint2_ && has_joint(eye_side) && eye_side >= 1 &&
               vertices_[size_t(eye_side) - 1].in_medium() && (eye_side >= 2 || end_.finite);
    }
    // B2's density of the light-side vertex of junction `eye_side` on the light ray from its
    // predecessor, the eye ray from endpoint `from` through the eye-side vertex (range: the light
    // ray's exit from the fog's ball, the test's scene sphere).
    float joint2_pdf(int eye_side, int from) const {
        const Vec3 o = endpoint(eye_side - 2), x = endpoint(eye_side - 1);
        const Vec3 e = endpoint(from), at = endpoint(eye_side);
        const Vec3 w = normalize(x - o);
        const float range = light_ray_range(SceneSphere{Vec3(0.0f), kFogRadius}, o, w);
        return JointLightDistanceSampler(o, w, e, normalize(at - e), range).pdf_l(length(x - o));
    }
    // q = p_J2 / p_J1 of that junction: only the light-side vertex's distance density differs.
    float joint2_ratio(int eye_side, int from) const {
        if (!has_joint2(eye_side)) return 0.0f;
        return joint2_pdf(eye_side, from) / segment(eye_side - 2, eye_side - 1).toward_end;
    }

    // --- query beams (P-B2D) ----------------------------------------------------------------

    // The eye side's P-B2D factor of vertex i (a medium vertex): eta_2D over the distance
    // density with which the eye's segment reaches it.
    float eye_query_beam(const VcmMis& mis, size_t i) const {
        if (!vertices_[i].in_medium()) return 0.0f;
        return mis.query_beam_factor(segment(int(i) + 1, int(i)).toward_end);
    }

    // --- photon beams (B-B1D) ----------------------------------------------------------------

    // sin of the angle between the light segment and the camera segment that reach vertex i.
    float beam_sin(size_t i) const { return length(cross(toward_light(i), toward_eye(i))); }
    // The fog's sigma_t as the weights use it (mean over the channels).
    float beam_sigma_t(size_t i) const {
        return (fog_ ? fog_ : &fog_medium_)->sigma_t(vertices_[i].p).average();
    }
    // Distance densities of vertex i from the light side (p_L) and the camera side (p_C).
    float light_distance(size_t i) const { return segment(int(i) - 1, int(i)).toward_end; }
    float camera_distance(size_t i) const { return segment(int(i) + 1, int(i)).toward_end; }

    // --- the integrator's recursion ---------------------------------------------------------

    SubpathStates trace_states(const VcmMis& mis) const {
        const size_t m = vertices_.size();
        SubpathStates st;
        st.light.resize(m);
        st.eye.resize(m);
        st.eye_before.resize(m);
        st.light_before.resize(m);
        st.light_carried_query.resize(m);
        st.light_carried_photon.resize(m);
        st.eye_carried_photon.resize(m);
        // Light subpath (generate_light_sample, next_vertex, sample_scattering): eqs. 31-36.
        // A volume light starts as generate_volume_light_sample starts it.
        MisQuantities q = end_.volume ? start_volume_light_mis(mis, end_.direct_pdf_a)
                                      : mis.start_light(end_.direct_pdf_a, end_.emission_pdf_w,
                                                        end_.cos_light, end_.delta);
        float carried = 0;         // J1: the previous vertex's connection term (segments.cpp)
        float carried_beam = 0;    // P-B2D: the previous vertex's scatter factor
        float carried_photon = 0;  // B-B1D: the previous vertex's deferred term
        for (size_t i = 0; i < m; ++i) {
            const PathVertex& v = vertices_[i];
            const Vec3 wo = toward_light(i);
            const SegmentDensities s = segment(int(i) - 1, int(i));
            st.light_before[i] = q;
            st.light_carried_query[i] = carried_beam;
            st.light_carried_photon[i] = carried_photon;
            mis.arrive(q, distance2_to_light_side(i), i > 0 || end_.finite, v.cos(wo), s.toward_end,
                       s.toward_start);
            // The junction whose eye-side vertex is i - 1, sampled from i.
            if (i >= 1 && has_joint(int(i) - 1))
                mis.add_joint_term(q, carried, joint_pdf(int(i), int(i) - 1, int(i) - 2), v.cos(wo),
                                   s.toward_end, joint2_ratio(int(i) - 1, int(i)));
            mis.add_query_beam_term(q, carried_beam, v.cos(wo), s.toward_end);
            mis.add_photon_beam_term(q, carried_photon, v.cos(wo), s.toward_end, s.toward_start,
                                     false, true);
            st.light[i] = q;
            if (i + 1 == m) break;
            const Vec3 wi = toward_eye(i);
            const BsdfPdf pdf_w = pdf_at(i, TransportMode::Importance, wo, wi);
            carried = mis.carried_connection_term(q, v.cos(wi), pdf_w.forward, v.specular);
            carried_beam = v.in_medium()
                               ? mis.carried_query_beam_term(v.cos(wi), pdf_w.forward, v.specular)
                               : 0.0f;
            carried_photon = v.in_medium()
                                 ? mis.carried_photon_beam_term(
                                       v.cos(wi), pdf_w.forward, v.specular, beam_sin(i),
                                       mis.photon_beam_light_factor(s.toward_end, beam_sigma_t(i)))
                                 : 0.0f;
            mis.scatter(q, v.cos(wi), pdf_w.forward, pdf_w.reverse, v.specular, v.in_medium());
        }
        // Eye subpath (trace_eye_path): the first segment starts at the camera.
        q = mis.start_camera(camera_pdf_w(-toward_eye(m - 1)));
        carried_photon = 0;
        float carried_joint2 = 0;  // J2: the last scatter's J1 share of its connection term
        for (size_t k = 0; k < m; ++k) {
            const size_t i = m - 1 - k;
            const PathVertex& v = vertices_[i];
            const Vec3 wo = toward_eye(i);
            const SegmentDensities s = segment(int(i) + 1, int(i));
            st.eye_before[i] = q;
            st.eye_carried_photon[i] = carried_photon;
            mis.arrive(q, distance2_to_eye_side(i), true, v.cos(wo), s.toward_end, s.toward_start);
            mis.add_photon_beam_term(q, carried_photon, v.cos(wo), s.toward_end, s.toward_start,
                                     true, true);
            // J2 of the junction two steps toward the camera (light-side vertex i + 1, resampled
            // on the light ray from here), carried from the scatter at i + 1.
            if (has_joint2(int(i) + 2))
                mis.add_eye_joint2_term(q, carried_joint2, joint2_pdf(int(i) + 2, int(i) + 3),
                                        v.cos(wo), s.toward_end);
            // The junction toward the camera (eye-side vertex i + 1, sampled from i + 2).
            mis.include_joint_junction(q, joint_ratio(int(i) + 1, int(i) + 2));
            st.eye[i] = q;
            const Vec3 wi = toward_light(i);
            const BsdfPdf pdf_w = pdf_at(i, TransportMode::Radiance, wo, wi);
            carried_joint2 = mis.carried_eye_joint2_term(q, joint_ratio(int(i) + 1, int(i) + 2),
                                                         v.cos(wi), pdf_w.forward, v.specular);
            carried_photon = v.in_medium()
                                 ? mis.carried_photon_beam_term(
                                       v.cos(wi), pdf_w.forward, v.specular, beam_sin(i),
                                       mis.photon_beam_eye_factor(s.toward_end, beam_sigma_t(i)))
                                 : 0.0f;
            mis.scatter(q, v.cos(wi), pdf_w.forward, pdf_w.reverse, v.specular, v.in_medium(),
                        eye_query_beam(mis, i));
        }
        // The eye subpath hits a finite light, or leaves the scene toward an infinite one.
        const SegmentDensities s = segment(0, kLightEnd);
        if (end_.finite)
            mis.arrive(q, distance2_to_light_side(0), true, end_.cos_light, s.toward_end,
                       s.toward_start);
        else
            mis.arrive(q, 0.0f, false, 1.0f, s.toward_end, s.toward_start);
        mis.add_photon_beam_term(q, carried_photon, end_.finite ? end_.cos_light : 1.0f,
                                 s.toward_end, s.toward_start, true, true);
        // J2 on the emission ray, vertex 0 its light-side vertex (for the emission weight).
        if (has_joint2(1))
            mis.add_eye_joint2_term(q, carried_joint2, joint2_pdf(1, 2), end_.cos_light,
                                    s.toward_end);
        st.eye_at_light = q;
        return st;
    }

    // Every technique that can sample the current path with the enabled families.
    std::vector<Technique> techniques(bool use_vc, bool use_vm, bool query_beams = false,
                                      bool photon_beams = false) const {
        const size_t m = vertices_.size();
        std::vector<Technique> list;
        if (use_vc && !end_.delta) list.push_back({TechniqueKind::Emission});
        if (use_vc && !vertices_[0].specular) list.push_back({TechniqueKind::Direct});
        if (use_vc && has_joint(0)) list.push_back({TechniqueKind::JointDirect});
        for (size_t a = 0; use_vc && a + 1 < m; ++a)
            if (!vertices_[a].specular && !vertices_[a + 1].specular)
                list.push_back({TechniqueKind::Connection, a});
        if (use_vc && !vertices_[m - 1].specular) list.push_back({TechniqueKind::Camera, m - 1});
        for (size_t a = 0; use_vc && a + 1 < m; ++a)
            if (!vertices_[a].specular && has_joint(int(a) + 1))
                list.push_back({TechniqueKind::JointConnection, a});
        for (size_t a = 0; use_vc && a + 1 < m; ++a)
            if (has_joint2(int(a) + 1)) list.push_back({TechniqueKind::Joint2Connection, a});
        for (size_t i = 0; use_vm && i < m; ++i)
            if (!vertices_[i].specular) list.push_back({TechniqueKind::Merge, i});
        for (size_t i = 0; query_beams && i < m; ++i)
            if (vertices_[i].in_medium()) list.push_back({TechniqueKind::QueryBeam, i});
        for (size_t i = 0; photon_beams && i < m; ++i)
            if (vertices_[i].in_medium() && !VcmMis::beams_parallel(beam_sin(i)))
                list.push_back({TechniqueKind::PhotonBeam, i});
        return list;
    }

    // A technique's weight as the integrator computes it.
    double weight(const VcmMis& mis, const SubpathStates& st, const Technique& t) const {
        const size_t m = vertices_.size();
        switch (t.kind) {
            case TechniqueKind::Emission:  // eq. 43 (trace_eye_path, emission)
                // A volume light: the eye's collision estimate at y (medium_emission).
                if (end_.volume)
                    return volume_emission_weight(mis, st.eye_at_light, end_.direct_pdf_a);
                return mis.weight_emission(st.eye_at_light, end_.direct_pdf_a, end_.emission_pdf_w,
                                           joint_ratio(0, 1));
            case TechniqueKind::Direct:  // eqs. 44-45 (direct_illumination)
            case TechniqueKind::JointDirect: {
                const PathVertex& v = vertices_[0];
                const Vec3 wo = toward_eye(0), wi = toward_light(0);
                const BsdfPdf pdf_w = pdf_at(0, TransportMode::Radiance, wo, wi);
                const SegmentDensities l = segment(0, kLightEnd);
                // B-B1D at the receiver, the emission segment as the photon beam.
                const float light_density =
                    end_.emission_pdf_w * v.cos(wi) / (end_.direct_pdf_w * end_.cos_light);
                const float eye_beam =
                    v.in_medium() ? mis.photon_beam_eye_term(
                                        beam_sin(0), camera_distance(0), beam_sigma_t(0),
                                        light_density * l.toward_start, light_density, true)
                                  : 0.0f;
                const DirectTechnique direct{
                    .bsdf_forward_w = pdf_w.forward,
                    .bsdf_reverse_w = pdf_w.reverse,
                    .light_pdf_w = end_.direct_pdf_w,
                    .emission_pdf_w = end_.emission_pdf_w,
                    .direct_pdf_w = end_.direct_pdf_w,
                    .cos_here = v.cos(wi),
                    .cos_light = end_.cos_light,
                    .delta_light = end_.delta,
                    .eye_medium = v.in_medium(),
                    .eye_query_beam = eye_query_beam(mis, 0),
                    .pass_to_light_probability = l.toward_end,
                    .distance_from_light = l.toward_start,
                    .eye_photon_beam = eye_beam,
                    .joint_ratio = joint_ratio(0, 1),
                    .eye_joint2 = has_joint2(1) ? mis.eye_joint2_term(st.eye[0], joint_ratio(1, 2),
                                                                      joint2_ratio(1, 2))
                                                : 0.0f};
                return t.kind == TechniqueKind::Direct ? mis.weight_direct(st.eye[0], direct)
                                                       : mis.weight_joint_direct(st.eye[0], direct);
            }
            case TechniqueKind::Connection:  // eqs. 40-41 (connect_vertices)
            case TechniqueKind::JointConnection:
            case TechniqueKind::Joint2Connection: {
                const size_t a = t.vertex, b = a + 1;
                const PathVertex &w = vertices_[a], &v = vertices_[b];
                const Vec3 d = toward_eye(a);  // from the light vertex a to the eye vertex b
                const float dist2 = length_squared(v.p - w.p);
                const BsdfPdf eye_pdf_w = pdf_at(b, TransportMode::Radiance, toward_eye(b), -d);
                const BsdfPdf light_pdf_w =
                    pdf_at(a, TransportMode::Importance, toward_light(a), d);
                const SegmentDensities l = segment(int(b), int(a));  // traced from the eye
                const float eye_pdf_a = eye_pdf_w.forward * w.cos(d) * l.toward_end / dist2;
                const float light_pdf_a = light_pdf_w.forward * v.cos(d) * l.toward_start / dist2;
                const ConnectionTechnique c{
                    .eye_pdf_a = eye_pdf_a,
                    .light_pdf_a = light_pdf_a,
                    .light_reverse_w = light_pdf_w.reverse,
                    .eye_reverse_w = eye_pdf_w.reverse,
                    .light_medium = w.in_medium(),
                    .eye_medium = v.in_medium(),
                    .eye_query_beam = eye_query_beam(mis, b),
                    // P-B2D at the light vertex: the eye vertex's density
                    // of it without the distance density.
                    .light_query_beam =
                        w.in_medium() ? mis.query_beam_term(eye_pdf_w.forward / dist2) : 0.0f,
                    // The light vertex sampled from the eye vertex; the eye
                    // vertex from its successor (the camera for the last).
                    .light_joint_ratio = joint_ratio(int(a), int(b)),
                    .joint_ratio = joint_ratio(int(b), int(b) + 1),
                    // J2: this junction, the one toward the light, and the one toward the camera
                    // (its light-side vertex b resampled on the connection from a).
                    .light_joint2_ratio = joint2_ratio(int(a), int(b)),
                    .joint2_ratio = joint2_ratio(int(b), int(b) + 1),
                    .eye_joint2 =
                        has_joint2(int(b) + 1)
                            ? mis.eye_joint2_term(st.eye[b], joint_ratio(int(b) + 1, int(b) + 2),
                                                  joint2_ratio(int(b) + 1, int(b) + 2))
                            : 0.0f,
                    // B-B1D at the light vertex (the connection as the query) and at the eye
                    // vertex (the connection as the photon beam).
                    .light_photon_beam = w.in_medium() ? mis.photon_beam_light_term(
                                                             length(cross(toward_light(a), d)),
                                                             eye_pdf_w.forward / dist2,
                                                             light_distance(a), beam_sigma_t(a))
                                                       : 0.0f,
                    .eye_photon_beam =
                        v.in_medium()
                            ? mis.photon_beam_eye_term(
                                  length(cross(toward_eye(b), d)), camera_distance(b),
                                  beam_sigma_t(b), light_pdf_a, light_pdf_w.forward / dist2, true)
                            : 0.0f};
                return t.kind == TechniqueKind::Connection
                           ? mis.weight_connection(st.light[a], st.eye[b], c)
                       : t.kind == TechniqueKind::JointConnection
                           ? mis.weight_joint_connection(st.light[a], st.eye[b], c)
                           : mis.weight_joint2_connection(st.light[a], st.eye[b], c);
            }
            case TechniqueKind::Camera: {  // eq. 46 (connect_to_camera)
                const size_t i = m - 1;
                const PathVertex& v = vertices_[i];
                const Vec3 d = toward_eye(i);
                const float dist2 = distance2_to_eye_side(i);
                const BsdfPdf pdf_w = pdf_at(i, TransportMode::Importance, toward_light(i), d);
                const SegmentDensities l = segment(int(i), int(m));  // traced to the camera
                const float camera_pdf_a = camera_pdf_w(-d) * v.cos(d) * l.toward_start / dist2;
                // J1 of the last vertex, sampled along the camera ray: its distance density from
                // the camera is the segment's toward_start here (traced from the vertex).
                const float joint = has_joint(int(i))
                                        ? joint_pdf(int(m), int(i), int(i) - 1) / l.toward_start
                                        : 0.0f;
                const float beam =
                    v.in_medium()
                        ? mis.query_beam_term(camera_pdf_w(-d) / dist2 / float(kLightPaths))
                        : 0.0f;
                const float photon_beam =
                    v.in_medium() ? mis.photon_beam_light_term(
                                        beam_sin(i), camera_pdf_w(-d) / dist2 / float(kLightPaths),
                                        light_distance(i), beam_sigma_t(i))
                                  : 0.0f;
                return mis.weight_camera(st.light[i],
                                         {.camera_pdf_a = camera_pdf_a,
                                          .light_reverse_w = pdf_w.reverse,
                                          .light_medium = v.in_medium(),
                                          .light_query_beam = beam,
                                          .light_joint_ratio = joint,
                                          .light_joint2_ratio = joint2_ratio(int(i), int(m)),
                                          .light_photon_beam = photon_beam});
            }
            case TechniqueKind::Merge: {  // eqs. 38-39 (merge)
                const size_t i = t.vertex;
                const BsdfPdf pdf_w =
                    pdf_at(i, TransportMode::Radiance, toward_eye(i), toward_light(i));
                return mis.weight_merge(
                    st.light[i], st.eye[i],
                    {.eye_forward_w = pdf_w.forward,
                     .eye_reverse_w = pdf_w.reverse,
                     .medium = vertices_[i].in_medium(),
                     .query_beam = eye_query_beam(mis, i),
                     .photon_beam =
                         vertices_[i].in_medium()
                             ? mis.photon_beam_merge_term(beam_sin(i), light_distance(i),
                                                          camera_distance(i), beam_sigma_t(i))
                             : 0.0f,
                     // J1 of the junction whose eye-side vertex is i, sampled from i + 1.
                     .light_joint_ratio = joint_ratio(int(i), int(i) + 1)});
            }
            case TechniqueKind::QueryBeam: {  // beams.cpp, query_beams
                // The eye subpath as if it had arrived at the photon's projection on the query
                // (here the photon itself), with the distance density left to the weight.
                const size_t i = t.vertex;
                const SegmentDensities s = segment(int(i) + 1, int(i));
                MisQuantities eye = st.eye_before[i];
                mis.arrive(eye, distance2_to_eye_side(i), true, 1.0f, 1.0f, s.toward_start);
                mis.add_photon_beam_term(eye, st.eye_carried_photon[i], 1.0f, 1.0f, s.toward_start,
                                         true, true);
                const BsdfPdf pdf_w =
                    pdf_at(i, TransportMode::Radiance, toward_eye(i), toward_light(i));
                return mis.weight_query_beam(
                    st.light[i], eye, s.toward_end,
                    {.eye_forward_w = pdf_w.forward,
                     .eye_reverse_w = pdf_w.reverse,
                     .medium = true,
                     .photon_beam = mis.photon_beam_light_term(beam_sin(i), 1.0f, light_distance(i),
                                                               beam_sigma_t(i))});
            }
            case TechniqueKind::PhotonBeam: {  // beams.cpp, photon_beams
                // Both subpaths as if they had arrived at the closest approach (here the vertex
                // itself), their distance densities left to the weight.
                const size_t i = t.vertex;
                const SegmentDensities sl = segment(int(i) - 1, int(i));
                MisQuantities light = st.light_before[i];
                mis.arrive(light, distance2_to_light_side(i), i > 0 || end_.finite, 1.0f, 1.0f,
                           sl.toward_start);
                mis.add_query_beam_term(light, st.light_carried_query[i], 1.0f, 1.0f);
                mis.add_photon_beam_term(light, st.light_carried_photon[i], 1.0f, 1.0f,
                                         sl.toward_start, false, true);
                const SegmentDensities sc = segment(int(i) + 1, int(i));
                MisQuantities eye = st.eye_before[i];
                mis.arrive(eye, distance2_to_eye_side(i), true, 1.0f, 1.0f, sc.toward_start);
                mis.add_photon_beam_term(eye, st.eye_carried_photon[i], 1.0f, 1.0f, sc.toward_start,
                                         true, true);
                const BsdfPdf pdf_w =
                    pdf_at(i, TransportMode::Radiance, toward_eye(i), toward_light(i));
                return mis.weight_photon_beam(light, eye, sl.toward_end, sc.toward_end, beam_sin(i),
                                              beam_sigma_t(i),
                                              {.eye_forward_w = pdf_w.forward,
                                               .eye_reverse_w = pdf_w.reverse,
                                               .medium = true});
            }
        }
        return 0;
    }

    std::vector<double> weights(const VcmMis& mis, const std::vector<Technique>& list) const {
        const SubpathStates st = trace_states(mis);
        std::vector<double> w;
        for (const Technique& t : list) w.push_back(weight(mis, st, t));
        return w;
    }

    // --- the reference: every technique's density of the whole path -------------------------

    // Directional density of scattering at vertex i; a delta lobe's is the same for every
    // technique that samples it, and is left out (1).
    double directional_pdf(size_t i, TransportMode mode, const Vec3& wo, const Vec3& wi) const {
        return vertices_[i].specular ? 1.0 : double(pdf_at(i, mode, wo, wi).forward);
    }

    // p_k^power / sum_j p_j^power over the listed techniques, from the density p_k with which
    // technique k samples the path (per unit area, or volume at medium vertices; the light end
    // per unit solid angle for infinite lights).
    std::vector<double> reference_weights(const std::vector<Technique>& list, int power,
                                          double eta_surface, double eta_volume,
                                          double eta_beam = 0, double eta_photon_beam = 0,
                                          bool short_beams = false) const {
        const size_t m = vertices_.size();
        // light_fwd[i], eye_fwd[i]: the light (eye) subpath's density of vertex i given the
        // vertices before it: direction, cosine at i, distance density at i, squared distance.
        std::vector<double> light_fwd(m), eye_fwd(m);
        for (size_t i = 0; i < m; ++i) {
            const double directional =
                i == 0 ? end_.emission_pdf_w
                       : directional_pdf(i - 1, TransportMode::Importance, toward_light(i - 1),
                                         toward_eye(i - 1));
            const double dist2 = i > 0 || end_.finite ? distance2_to_light_side(i) : 1.0;
            light_fwd[i] = directional * vertices_[i].cos(toward_light(i)) *
                           segment(int(i) - 1, int(i)).toward_end / dist2;
        }
        for (size_t i = 0; i < m; ++i) {
            const double directional =
                i + 1 == m ? camera_pdf_w(-toward_eye(m - 1))
                           : directional_pdf(i + 1, TransportMode::Radiance, toward_eye(i + 1),
                                             toward_light(i + 1));
            eye_fwd[i] = directional * vertices_[i].cos(toward_eye(i)) *
                         segment(int(i) + 1, int(i)).toward_end / distance2_to_eye_side(i);
        }
        // The eye subpath's density of the light end (an infinite light's: solid angle).
        const double eye_light =
            directional_pdf(0, TransportMode::Radiance, toward_eye(0), toward_light(0)) *
            segment(0, kLightEnd).toward_end *
            (end_.finite ? end_.cos_light / distance2_to_light_side(0) : 1.0);
        auto light_prefix = [&](size_t count) {  // vertices 0 .. count-1 from the light
            double p = 1;
            for (size_t i = 0; i < count; ++i) p *= light_fwd[i];
            return p;
        };
        auto eye_suffix = [&](size_t from) {  // vertices m-1 .. from from the eye
            double p = 1;
            for (size_t i = from; i < m; ++i) p *= eye_fwd[i];
            return p;
        };
        std::vector<double> p;
        for (const Technique& t : list) {
            switch (t.kind) {
                case TechniqueKind::Emission:
                    p.push_back(eye_suffix(0) * eye_light);
                    break;
                case TechniqueKind::Direct:
                    p.push_back(end_.direct_pdf_a * eye_suffix(0));
                    break;
                case TechniqueKind::JointDirect:  // vertex 0's distance density replaced by J1's
                    p.push_back(end_.direct_pdf_a * eye_fwd[0] / segment(1, 0).toward_end *
                                joint_pdf(1, 0, kLightEnd) * eye_suffix(1));
                    break;
                case TechniqueKind::Connection:
                    p.push_back(light_prefix(t.vertex + 1) * eye_suffix(t.vertex + 1));
                    break;
                case TechniqueKind::Camera:  // every light subpath is connected to the camera
                    p.push_back(kLightPaths * light_prefix(m));
                    break;
                case TechniqueKind::JointConnection: {
                    // The eye-side vertex's distance density replaced by J1's, written out.
                    const size_t b = t.vertex + 1;
                    const double joint = eye_fwd[b] / segment(int(b) + 1, int(b)).toward_end *
                                         joint_pdf(int(b) + 1, int(b), int(t.vertex));
                    p.push_back(light_prefix(t.vertex + 1) * joint * eye_suffix(b + 1));
                    break;
                }
                case TechniqueKind::Joint2Connection: {
                    // Both junction vertices' distance densities replaced, written out: the
                    // light-side one by B2's on the light ray, the eye-side one by J1's.
                    const size_t a = t.vertex, b = a + 1;
                    const double joint = eye_fwd[b] / segment(int(b) + 1, int(b)).toward_end *
                                         joint_pdf(int(b) + 1, int(b), int(a));
                    const double light = light_fwd[a] / segment(int(a) - 1, int(a)).toward_end *
                                         joint2_pdf(int(b), int(b) + 1);
                    p.push_back(light_prefix(a) * light * joint * eye_suffix(b + 1));
                    break;
                }
                case TechniqueKind::Merge: {  // the light subpath ends within r of the eye's
                    const double eta = vertices_[t.vertex].in_medium() ? eta_volume : eta_surface;
                    p.push_back(eta * light_prefix(t.vertex + 1) * eye_suffix(t.vertex));
                    break;
                }
                case TechniqueKind::QueryBeam:  // the merge without the eye's distance sample
                    p.push_back(eta_beam * light_prefix(t.vertex + 1) * eye_suffix(t.vertex) /
                                segment(int(t.vertex) + 1, int(t.vertex)).toward_end);
                    break;
                case TechniqueKind::PhotonBeam: {
                    // The merge without either side's distance sample: eta_1 N sin(theta) over
                    // both distance densities; a short beam covers the vertex with the light
                    // side's probability of passing it, P_pass / p_L = 1 / sigma_t here.
                    const size_t i = t.vertex;
                    const double p_l = light_distance(i), p_c = camera_distance(i);
                    const double q_l = short_beams ? 1.0 / beam_sigma_t(i) : 1.0 / p_l;
                    p.push_back(eta_photon_beam * beam_sin(i) * q_l / p_c * light_prefix(i + 1) *
                                eye_suffix(i));
                    break;
                }
            }
        }
        double sum = 0;
        for (double& x : p) sum += (x = std::pow(x, power));
        for (double& x : p) x /= sum;
        return p;
    }

    // Checks both properties for one family (with the listed techniques' weights).
    // Query beams (P-B2D) beside BPT, VCM, BPM and alone, with a beam radius unlike the point
    // radius (as UPBP's schedules have it): the merge factor of a medium vertex is then per
    // vertex, added at the next arrival on light subpaths. Photon beams (B-B1D) beside BPT,
    // beside everything (UPBP), beside BPM and alone; long and short beams; both constants
    // eta_1 of the spec (SmallUPBP's r / 2 and the kernel's support 2 r).
    void check_beam_families(int power, double radius, double eta_surface, double eta_volume) {
        const double eta_beam = kPi * 0.25 * radius * radius * kLightPaths;
        for (const auto& [vc, vm, name] :
             {std::tuple{true, false, "BPT+PB2D"}, std::tuple{true, true, "VCM+PB2D"},
              std::tuple{false, true, "BPM+PB2D"}, std::tuple{false, false, "PB2D"}})
            check_family(power, vc, vm, eta_surface, eta_volume, name, 0, eta_beam);
        const double r_1 = 0.5 * radius;
        for (const double eta_1 : {0.5 * r_1, 2.0 * r_1})
            for (const bool short_beams : {false, true}) {
                SCOPED_TRACE(::testing::Message() << "eta_1 " << eta_1 << ", "
                                                  << (short_beams ? "short" : "long") << " beams");
                for (const auto& [vc, vm, qb, name] :
                     {std::tuple{true, false, 0.0, "BPT+BB1D"},
                      std::tuple{true, true, eta_beam, "UPBP (all)"},
                      std::tuple{false, true, 0.0, "BPM+BB1D"},
                      std::tuple{false, false, 0.0, "BB1D"}})
                    check_family(power, vc, vm, eta_surface, eta_volume, name, 0, qb,
                                 eta_1 * kLightPaths, short_beams);
            }
    }

    void check_family(int power, bool use_vc, bool use_vm, double eta_surface, double eta_volume,
                      const char* name, int joint = 0, double eta_beam = 0,
                      double eta_photon_beam = 0, bool short_beams = false) {
        joint_ = joint > 0;
        joint_light_ = joint > 1;
        joint2_ = joint > 2;
        const std::vector<Technique> list =
            techniques(use_vc, use_vm, eta_beam > 0, eta_photon_beam > 0);
        if (list.empty()) return;
        const VcmMis mis(power,
                         MisTechniques{.connections = use_vc,
                                       .surface_eta = use_vm ? eta_surface : 0.0,
                                       .point_eta = use_vm ? eta_volume : 0.0,
                                       .query_beam_eta = eta_beam,
                                       .photon_beam_eta = eta_photon_beam,
                                       .short_photon_beams = short_beams},
                         kLightPaths);
        const std::vector<double> w = weights(mis, list);
        const std::vector<double> reference = reference_weights(
            list, power, eta_surface, eta_volume, eta_beam, eta_photon_beam, short_beams);
        const bool merges = std::any_of(list.begin(), list.end(), [](const Technique& t) {
            return t.kind == TechniqueKind::Merge;
        });
        for (const Technique& t : list) {
            joint_checked_ += t.kind == TechniqueKind::JointConnection;
            joint_direct_checked_ += t.kind == TechniqueKind::JointDirect;
            joint2_checked_ += t.kind == TechniqueKind::Joint2Connection;
            // J2 from a deeper light vertex: the light ray starts at a scattering vertex.
            joint2_deep_checked_ += t.kind == TechniqueKind::Joint2Connection && t.vertex >= 1;
            joint_with_merges_checked_ += merges && t.kind == TechniqueKind::JointConnection;
            query_beams_checked_ += t.kind == TechniqueKind::QueryBeam;
            photon_beams_checked_ += t.kind == TechniqueKind::PhotonBeam;
        }
        double sum = 0;
        for (double x : w) sum += x;
        // float arithmetic over a handful of terms: 1e-4 relative.
        EXPECT_NEAR(sum, 1.0, 1e-4) << name;
        for (size_t k = 0; k < list.size(); ++k)
            EXPECT_NEAR(w[k], reference[k], 1e-4 + 1e-3 * reference[k])
                << name << ": technique " << int(list[k].kind) << " at vertex " << list[k].vertex;
        // With J2, the emission weight is small in fog (the eye rarely hits the light from a
        // medium vertex) and its J2 term is below the absolute tolerance above: checked relative.
        for (size_t k = 0; joint2_ && k < list.size(); ++k) {
            if (list[k].kind == TechniqueKind::Emission) {
                EXPECT_NEAR(w[k], reference[k], 1e-3 * reference[k] + 1e-12)
                    << name << ": the emission weight, relative";
            }
        }
    }

    static Vec3 random_direction_above(Rng& rng, float min_cos) {
        Vec3 w = warp::square_to_uniform_hemisphere(rng.next_2d());
        w.z = std::max(w.z, min_cos);
        return normalize(w);
    }
    static Vec3 random_normal_facing(Rng& rng, const Vec3& toward) {
        return Frame::from_normal(toward).to_world(random_direction_above(rng, 0.3f));
    }

    DiffuseBsdf diffuse_;
    PhongBsdf glossy_;
    ConductorBsdf mirror_;
    TriangleMesh rectangle_;
    HomogeneousMedium fog_medium_;
    const Medium* grid_fog_ = nullptr;  // set: fog paths are in this grid medium instead
    const Medium* fog_ = nullptr;       // the medium filling the scene; null: vacuum
    bool joint_ = false;            // the J1 techniques are enabled (bpt --joint-connections on)
    bool joint_light_ = false;      // J1 at s = 1 as well (next-event estimation's sibling)
    bool joint2_ = false;           // J2 as well (bpt --joint-connections all)
    int joint2_checked_ = 0;        // J2 weights checked so far
    int joint2_deep_checked_ = 0;   // of them, on a light ray from a scattering vertex
    int joint_checked_ = 0;         // J1 weights checked so far
    int joint_direct_checked_ = 0;  // J1 at s = 1 weights checked so far
    int joint_with_merges_checked_ = 0;  // of which beside merges (vcm)
    int query_beams_checked_ = 0;        // P-B2D weights checked so far
    int photon_beams_checked_ = 0;       // B-B1D weights checked so far
    float fog_exit_ = 0;                 // from the first vertex toward an infinite light
    PerspectiveCamera camera_;
    std::vector<PathVertex> vertices_;  // light order: vertices_[0] is next to the light
    LightKind kind_ = LightKind::Area;
    std::unique_ptr<Light> light_;
    Vec3 light_point_, light_normal_, to_light_;
    LightEnd end_;
};

constexpr LightKind kAllLights[] = {LightKind::Area, LightKind::Point, LightKind::Directional,
                                    LightKind::Constant};

TEST_F(MisSumTest, WeightsOfAllTechniquesSumToOne) {
    const std::vector<std::vector<Material>> paths = {
        {Material::Diffuse},
        {Material::Diffuse, Material::Diffuse},
        {Material::Glossy, Material::Diffuse, Material::Diffuse},
        {Material::Diffuse, Material::Mirror, Material::Diffuse},
        {Material::Mirror, Material::Diffuse, Material::Glossy},
        {Material::Diffuse, Material::Glossy, Material::Mirror},
        {Material::Glossy, Material::Diffuse, Material::Mirror, Material::Diffuse,
         Material::Glossy},
    };
    Rng rng(StreamKey{2024, 0, 1, 0});
    int checked = 0;
    for (const auto& materials : paths)
        for (LightKind kind : kAllLights)
            for (int trial = 0; trial < 20; ++trial) {
                if (!build_path(rng, materials, kind)) continue;
                for (int power : {1, 2}) {
                    const double eta = kPi * 0.02 * 0.02 * kLightPaths;
                    SCOPED_TRACE(::testing::Message()
                                 << "path of " << materials.size() << " vertices, light kind "
                                 << int(kind) << ", trial " << trial << ", power " << power);
                    check_family(power, true, false, eta, eta, "BPT");
                    check_family(power, true, true, eta, eta, "VCM");
                    check_family(power, false, true, eta, eta, "BPM");
                    ++checked;
                }
            }
    EXPECT_GT(checked, 300);
}

// Paths in fog: medium vertices, surface vertices, and both, as a path in fog bouncing off walls;
// BPT and VCM with J1 connections, and query beams (UPBP's long camera query) beside each family.
TEST_F(MisSumTest, WeightsOfAllTechniquesSumToOneInAMedium) {
    using M = Material;
    const std::vector<std::vector<Material>> paths = {
        {M::Medium},
        {M::Diffuse},
        {M::Medium, M::Medium},
        {M::Medium, M::Diffuse},
        {M::Diffuse, M::Medium},
        {M::Glossy, M::Medium, M::Diffuse},
        {M::Medium, M::Mirror, M::Medium},
        {M::Mirror, M::Medium, M::Glossy},
        {M::Medium, M::Medium, M::Medium},
        {M::Diffuse, M::Medium, M::Mirror, M::Medium, M::Glossy},
        {M::Medium, M::Diffuse, M::Medium, M::Glossy, M::Medium},
        // Runs of medium vertices: J2 on light rays from scattering vertices at every depth,
        // with the light subpath's deferred term of junctions 2 and beyond.
        {M::Medium, M::Medium, M::Medium, M::Medium},
        {M::Glossy, M::Medium, M::Medium, M::Medium, M::Diffuse},
    };
    Rng rng(StreamKey{2025, 0, 1, 0});
    int checked = 0, with_medium_vertex = 0;
    for (const auto& materials : paths)
        for (LightKind kind : kAllLights)
            for (int trial = 0; trial < 12; ++trial) {
                if (!build_path(rng, materials, kind, true)) continue;
                bool medium_vertex = false;
                for (const PathVertex& v : vertices_) medium_vertex |= v.in_medium();
                // Two radii: merging weak, and merging dominant at surfaces and strong in the
                // medium; the volume eta differs from the surface eta by far either way.
                for (double radius : {0.05, 0.15})
                    for (int power : {1, 2}) {
                        const double eta_surface = kPi * radius * radius * kLightPaths;
                        const double eta_volume =
                            4.0 / 3.0 * kPi * radius * radius * radius * kLightPaths;
                        SCOPED_TRACE(::testing::Message()
                                     << "fog path of " << materials.size()
                                     << " vertices, light kind " << int(kind) << ", trial " << trial
                                     << ", radius " << radius << ", power " << power);
                        check_family(power, true, false, eta_surface, eta_volume, "BPT");
                        check_family(power, true, false, eta_surface, eta_volume, "BPT+J1", 1);
                        check_family(power, true, false, eta_surface, eta_volume, "BPT+J1 s>=1", 2);
                        // J2 (segment-segment) beside J1 and J1 at s = 1, as bpt runs it.
                        check_family(power, true, false, eta_surface, eta_volume, "BPT+J1+J2", 3);
                        check_family(power, true, true, eta_surface, eta_volume, "VCM");
                        check_family(power, true, true, eta_surface, eta_volume, "VCM+J1", 1);
                        check_family(power, true, true, eta_surface, eta_volume, "VCM+J1 s>=1", 2);
                        check_family(power, false, true, eta_surface, eta_volume, "BPM");
                        // Query beams and photon beams beside each family.
                        check_beam_families(power, radius, eta_surface, eta_volume);
                        ++checked;
                        with_medium_vertex += medium_vertex;
                    }
            }
    EXPECT_GT(checked, 500);
    EXPECT_GT(with_medium_vertex, 400);
    EXPECT_GT(joint_checked_, 800);
    EXPECT_GT(joint_with_merges_checked_, 400);
    EXPECT_GT(joint_direct_checked_, 200);
    EXPECT_GT(joint2_checked_, 300);
    EXPECT_GT(joint2_deep_checked_, 150);
    EXPECT_GT(query_beams_checked_, 1500);
    EXPECT_GT(photon_beams_checked_, 10000);
}

// A grid fog over the fog's ball: a cube of 28 (centred at the origin) of 6^3 voxels with
// sigma_t between 0.05 and 0.65 (one channel, or three that differ), albedo 0.8, the fog's HG.
std::unique_ptr<HeterogeneousMedium> grid_fog(bool grey, Rng& rng) {
    VolumeGridData d;
    d.xres = d.yres = d.zres = 6;
    d.channels = grey ? 1 : 3;
    for (size_t i = 0; i < d.voxel_count() * size_t(d.channels); ++i)
        d.values.push_back(0.05f + 0.6f * rng.next_1d());
    auto volume = std::make_shared<GridVolume>(
        std::move(d), Transform::translate(Vec3(-14.0f)) * Transform::scale(Vec3(28.0f)));
    return std::make_unique<HeterogeneousMedium>(volume,
                                                 std::make_shared<ConstantVolume>(Rgb(0.8f)), 1.0f,
                                                 std::make_shared<HenyeyGreenstein>(0.4f));
}

// Photon beams in a grid medium (docs/design/media.md, "Photon beams in grid media"): the fog paths
// in a grid fog, whose distance densities are the midpoint-rule proxies (different from either end,
// sigma_t varying from vertex to vertex). B-B1D beside BPT, beside everything, beside BPM and
// alone, with both constants eta_1; long beams in a grey and a chromatic grid, short beams in both
// (in the chromatic grid on one-piece segments only: finite lights). The weights must sum to one
// and equal the written-out ratios, the short beam's coverage P_pass / p_L taken as 1 / sigma_t(x)
// as in homogeneous media.
TEST_F(MisSumTest, PhotonBeamWeightsSumToOneInAGridMedium) {
    using M = Material;
    const std::vector<std::vector<Material>> paths = {
        {M::Medium},
        {M::Medium, M::Medium},
        {M::Medium, M::Diffuse},
        {M::Diffuse, M::Medium},
        {M::Medium, M::Mirror, M::Medium},
        {M::Medium, M::Medium, M::Medium},
        {M::Medium, M::Diffuse, M::Medium, M::Glossy, M::Medium},
    };
    Rng rng(StreamKey{2026, 0, 1, 0});
    int checked = 0, short_checked = 0;
    for (const bool grey : {true, false}) {
        const std::unique_ptr<HeterogeneousMedium> grid = grid_fog(grey, rng);
        grid_fog_ = grid.get();
        for (const auto& materials : paths)
            for (LightKind kind : kAllLights)
                for (int trial = 0; trial < 6; ++trial) {
                    if (!build_path(rng, materials, kind, true)) continue;
                    for (double radius : {0.05, 0.15})
                        for (int power : {1, 2}) {
                            const double eta_surface = kPi * radius * radius * kLightPaths;
                            const double eta_volume =
                                4.0 / 3.0 * kPi * radius * radius * radius * kLightPaths;
                            const double eta_beam = kPi * 0.25 * radius * radius * kLightPaths;
                            const double r_1 = 0.5 * radius;
                            for (const double eta_1 : {0.5 * r_1, 2.0 * r_1})
                                for (const bool short_beams : {false, true}) {
                                    // Chromatic grids carry short beams on segments of one
                                    // piece only (the sampling walk's pass weight replayed,
                                    // docs/design/media.md); toward an infinite light a segment has
                                    // two (the fog, then vacuum), which the model does not
                                    // mark, so those lights are left out here.
                                    if (short_beams && !grey &&
                                        (kind == LightKind::Directional ||
                                         kind == LightKind::Constant))
                                        continue;
                                    SCOPED_TRACE(
                                        ::testing::Message()
                                        << (grey ? "grey" : "chromatic") << " grid fog path of "
                                        << materials.size() << " vertices, light kind " << int(kind)
                                        << ", trial " << trial << ", radius " << radius
                                        << ", power " << power << ", eta_1 " << eta_1 << ", "
                                        << (short_beams ? "short" : "long") << " beams");
                                    for (const auto& [vc, vm, qb, name] :
                                         {std::tuple{true, false, 0.0, "BPT+BB1D"},
                                          std::tuple{true, true, eta_beam, "UPBP (all)"},
                                          std::tuple{false, true, 0.0, "BPM+BB1D"},
                                          std::tuple{false, false, 0.0, "BB1D"}}) {
                                        const int before = photon_beams_checked_;
                                        check_family(power, vc, vm, eta_surface, eta_volume, name,
                                                     0, qb, eta_1 * kLightPaths, short_beams);
                                        short_checked +=
                                            short_beams ? photon_beams_checked_ - before : 0;
                                    }
                                    ++checked;
                                }
                        }
                }
    }
    grid_fog_ = nullptr;
    EXPECT_GT(checked, 500);
    EXPECT_GT(photon_beams_checked_, 3000);
    EXPECT_GT(short_checked, 1000);
}

// Paths that start at a volume light (a point y of an emitting medium: upbp with emitting media,
// docs/design/media.md "Emitting media as lights") in the homogeneous fog and in grey and chromatic
// grid fogs: the eye's collision emission at y (s = 0), next-event estimation to y (s = 1), every
// connection, merge and camera connection, and upbp's query beams (P-B2D) and photon beams
// (B-B1D, the light's first segment from y a beam like any other), beside BPT, beside
// everything, beside BPM and alone. No technique samples y itself by a merge or a beam (y is not
// stored, as an area light's point is not), so the list is the other lights'. The weights must
// sum to one and equal the written-out ratios.
TEST_F(MisSumTest, VolumeLightWeightsSumToOneWithBeams) {
    using M = Material;
    const std::vector<std::vector<Material>> paths = {
        {M::Medium},
        {M::Diffuse},
        {M::Medium, M::Medium},
        {M::Medium, M::Diffuse},
        {M::Diffuse, M::Medium},
        {M::Medium, M::Mirror, M::Medium},
        {M::Medium, M::Medium, M::Medium},
        {M::Medium, M::Diffuse, M::Medium, M::Glossy, M::Medium},
    };
    Rng rng(StreamKey{2027, 0, 1, 0});
    int checked = 0, query_before = query_beams_checked_;
    int emission_checked = 0, direct_checked = 0;
    // 0: the homogeneous fog; 1: a grey grid fog; 2: a chromatic one.
    for (const int fog : {0, 1, 2}) {
        std::unique_ptr<HeterogeneousMedium> grid;
        if (fog > 0) grid = grid_fog(fog == 1, rng);
        grid_fog_ = grid.get();
        for (const auto& materials : paths)
            for (int trial = 0; trial < 8; ++trial) {
                if (!build_path(rng, materials, LightKind::Volume, true)) continue;
                for (const Technique& t : techniques(true, false)) {
                    emission_checked += t.kind == TechniqueKind::Emission;
                    direct_checked += t.kind == TechniqueKind::Direct;
                }
                for (double radius : {0.05, 0.15})
                    for (int power : {1, 2}) {
                        const double eta_surface = kPi * radius * radius * kLightPaths;
                        const double eta_volume =
                            4.0 / 3.0 * kPi * radius * radius * radius * kLightPaths;
                        SCOPED_TRACE(::testing::Message()
                                     << "fog " << fog << ", path of " << materials.size()
                                     << " vertices, trial " << trial << ", radius " << radius
                                     << ", power " << power);
                        check_family(power, true, false, eta_surface, eta_volume, "BPT");
                        check_family(power, true, true, eta_surface, eta_volume, "VCM");
                        check_family(power, false, true, eta_surface, eta_volume, "BPM");
                        check_beam_families(power, radius, eta_surface, eta_volume);
                        ++checked;
                    }
            }
    }
    grid_fog_ = nullptr;
    EXPECT_GT(checked, 300);
    EXPECT_GT(emission_checked, 100);
    EXPECT_GT(direct_checked, 100);
    EXPECT_GT(query_beams_checked_ - query_before, 1000);
    EXPECT_GT(photon_beams_checked_, 5000);
}

// The test model's segment densities are those of the integrator's SegmentDensityBuilder: one
// piece in the fog, and a piece in the fog followed by vacuum (toward an infinite light).
TEST_F(MisSumTest, SegmentDensitiesMatchTheIntegrators) {
    const Ray ray(Vec3(0.0f), Vec3(0, 0, 1));
    const float t = 1.7f;
    for (bool start_medium : {false, true})
        for (bool end_medium : {false, true}) {
            SegmentDensityBuilder one(start_medium);
            one.add_piece(&fog_medium_, ray, t);
            const SegmentDensities d = one.finish(end_medium);
            const auto density = [&](bool medium) {
                return medium ? fog_medium_.pdf_scatter_l(ray, t)
                              : fog_medium_.probability_pass(ray, t);
            };
            EXPECT_FLOAT_EQ(d.toward_end, density(end_medium));
            EXPECT_FLOAT_EQ(d.toward_start, density(start_medium));
        }
    for (bool start_medium : {false, true}) {
        // From a vertex out of the fog to infinity, and from infinity into the fog to a vertex.
        SegmentDensityBuilder out(start_medium);
        out.add_piece(&fog_medium_, ray, t);
        out.add_piece(nullptr, ray, kInfinity);
        const SegmentDensities d_out = out.finish(false);
        SegmentDensityBuilder in(false);
        in.add_piece(nullptr, ray, 5.0f);
        in.add_piece(&fog_medium_, ray, t);
        const SegmentDensities d_in = in.finish(start_medium);
        const float at_vertex =
            start_medium ? fog_medium_.pdf_scatter_l(ray, t) : fog_medium_.probability_pass(ray, t);
        EXPECT_FLOAT_EQ(d_out.toward_end, fog_medium_.probability_pass(ray, t));
        EXPECT_FLOAT_EQ(d_out.toward_start, at_vertex);
        EXPECT_FLOAT_EQ(d_in.toward_end, at_vertex);
        EXPECT_FLOAT_EQ(d_in.toward_start, fog_medium_.probability_pass(ray, t));
    }
}

// Where short photon beams live (SegmentDensities::short_beam_support): any segment through
// vacuum, homogeneous media and grey grids; in a chromatic grid a segment of one piece only (its
// weight is the sampling walk's, replayed), read the same from either end.
TEST_F(MisSumTest, ShortBeamSupportOfChromaticGridsIsOnePieceOnly) {
    Rng rng(StreamKey{9, 0, 1, 0});
    const std::unique_ptr<HeterogeneousMedium> grey = grid_fog(true, rng);
    const std::unique_ptr<HeterogeneousMedium> rgb = grid_fog(false, rng);
    const Ray ray(Vec3(0.0f), Vec3(0, 0, 1));
    auto support = [&](std::initializer_list<const Medium*> pieces) {
        SegmentDensityBuilder b(true);
        for (const Medium* m : pieces) b.add_piece(m, ray, 1.0f);
        return b.finish(true).short_beam_support;
    };
    EXPECT_TRUE(support({rgb.get()}));
    EXPECT_TRUE(support({grey.get(), nullptr, &fog_medium_}));
    EXPECT_FALSE(support({rgb.get(), nullptr}));
    EXPECT_FALSE(support({nullptr, rgb.get()}));
    EXPECT_FALSE(support({&fog_medium_, rgb.get(), grey.get()}));
}

// The test must be able to fail: dropping one technique breaks the sum.
TEST_F(MisSumTest, DetectsAMissingTechnique) {
    Rng rng(StreamKey{7, 0, 1, 0});
    ASSERT_TRUE(build_path(rng, {Material::Diffuse, Material::Diffuse}, LightKind::Area));
    const double eta = kPi * 0.02 * 0.02 * kLightPaths;
    const VcmMis bpt_mis(2, true, false, eta, kLightPaths);
    const std::vector<double> full = weights(bpt_mis, techniques(true, false));
    double sum = 0;
    for (double w : full) sum += w;
    EXPECT_NEAR(sum, 1.0, 1e-4);
    // Merging weights alone (with connections' weights computed as if merging were on) must
    // not sum to one.
    const std::vector<double> merges =
        weights(VcmMis(2, true, true, eta, kLightPaths), techniques(false, true));
    double merges_only = 0;
    for (double w : merges) merges_only += w;
    EXPECT_LT(merges_only, 0.999);
}

// The reference catches what the sum cannot: medium vertices merged with the surface eta.
TEST_F(MisSumTest, DetectsTheSurfaceEtaInTheMedium) {
    Rng rng(StreamKey{8, 0, 1, 0});
    ASSERT_TRUE(build_path(rng, {Material::Medium, Material::Medium}, LightKind::Area, true));
    const double r = 0.1, eta_surface = kPi * r * r * kLightPaths;
    const double eta_volume = 4.0 / 3.0 * kPi * r * r * r * kLightPaths;
    const std::vector<Technique> list = techniques(true, true);
    const std::vector<double> wrong =
        weights(VcmMis(2, true, true, eta_surface, kLightPaths, eta_surface), list);
    const std::vector<double> reference = reference_weights(list, 2, eta_surface, eta_volume);
    double sum = 0, max_error = 0;
    for (size_t k = 0; k < list.size(); ++k) {
        sum += wrong[k];
        max_error = std::max(max_error, std::abs(wrong[k] - reference[k]));
    }
    EXPECT_NEAR(sum, 1.0, 1e-4);  // consistent, so the sum cannot tell
    EXPECT_GT(max_error, 0.01);
}

}  // namespace
}  // namespace render
