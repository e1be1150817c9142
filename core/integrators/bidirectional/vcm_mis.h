#pragma once

// The MIS arithmetic of vertex connection and merging, as pure functions: how the recursive
// partial weights dVCM, dVC and dVM of a subpath start, how they are updated along it, and how
// each technique's weight is computed from them. Equation numbers refer to the technical report
// "Implementing Vertex Connection and Merging" (Georgiev 2012). The integrator
// (core/integrators/bidirectional/) and the test that checks that the weights of all techniques
// sampling one path sum to one (tests/unit/integrators/vcm_mis_test.cpp) use these same functions.
//
// Densities in solid angle (_w) or area (_a; volume at a medium vertex); selection
// probabilities are discrete (_probability); "mis(p)" is p^beta (beta = 2: power heuristic,
// beta = 1: balance heuristic). Russian roulette is not part of any density here: the weights
// only need to sum to one over the techniques, and roulette is compensated in the throughput.

#include <cmath>

namespace render {

// Merges in media come in two kinds (UPBP, Krivanek et al. 2014; ALGORITHMS-NEXT.md 4.3):
// photon points merged with a distance-sampled eye vertex (P-P3D, eta = 4/3 pi r^3 N) and
// photon points gathered along the whole camera segment, the "long query beam" (P-B2D, the beam
// radiance estimate). P-B2D does not sample the eye vertex's distance, so its density at a
// medium vertex x is the point density's with the camera side's distance density p_t(x)
// replaced by pi r_2^2 N: its merge factor is mis(eta_2D / p_t(x)), a per-vertex quantity.
// The eye subpath knows p_t of its own vertices when it reaches them (query_beam_factor); a
// light subpath learns it for vertex x_i only when it reaches x_{i+1} (it is the reverse
// density of that segment), so the term is carried and added by add_query_beam_term.
//
// dVM is kept without the merging normalisation of the vertex it belongs to (it holds the
// report's dVM times eta_VCM of the subpath's current end vertex): with media, merges happen at
// surfaces (eta = pi r^2 N) and in volumes (eta = 4/3 pi r^3 N, photon points), so the end
// vertex's eta is known only when the next vertex is, and each weight applies it at the vertex
// where the merge happens. With one eta everywhere this is the report's arithmetic exactly.
struct MisQuantities {
    float dVCM = 0, dVC = 0, dVM = 0;
};

// What each technique's weight needs besides the subpaths' MisQuantities, as named fields
// (call sites use designated initialisers). Defaults mean: surface vertices, no media on the
// way.

// Eqs. (44) and (45): next-event estimation from an eye vertex (the receiver).
struct DirectTechnique {
    // The receiver's densities toward the light (forward) and back along the eye path (reverse).
    float bsdf_forward_w = 0;
    float bsdf_reverse_w = 0;
    // Selection probability times the light's solid-angle density at the receiver.
    float light_pdf_w = 0;
    // The light's own densities (the selection probability cancels in their ratio).
    float emission_pdf_w = 0;
    float direct_pdf_w = 0;
    float cos_here = 0;   // at the receiver (1 in a medium)
    float cos_light = 0;  // at the light
    bool delta_light = false;
    bool eye_medium = false;   // the receiver is a medium vertex
    float eye_query_beam = 0;  // the receiver's VcmMis::query_beam_factor (0: none)
    // Through media: the probability of passing every medium toward the light, and the
    // distance density of reaching the receiver from the light (per unit length at a medium
    // receiver, the probability of passing every medium at a surface).
    float pass_to_light_probability = 1.0f;
    float distance_from_light = 1.0f;
    // B-B1D at the receiver, the light's emission segment as the photon beam:
    // VcmMis::photon_beam_eye_term (0: none).
    float eye_photon_beam = 0;
    // J1 at s = 1 (the receiver, a medium vertex, sampled from the eye's previous vertex toward
    // the light point instead of by distance sampling): its density over this technique's; 0
    // where there is none (ConnectionTechnique::joint_ratio).
    float joint_ratio = 0;
    // J2 of the junction toward the camera (the receiver sampled on the light's emission ray by
    // B2, its eye-side neighbour by J1): VcmMis::eye_joint2_term (0: none).
    float eye_joint2 = 0;
};

// Eqs. (40) and (41): connecting an eye vertex to a light vertex.
struct ConnectionTechnique {
    // The eye vertex's density of sampling the light vertex (area, or volume for a medium
    // vertex, with the distance sampling through media included); light_pdf_a the reverse.
    float eye_pdf_a = 0;
    float light_pdf_a = 0;
    // Each vertex's density back along its own subpath given the connection direction.
    float light_reverse_w = 0;
    float eye_reverse_w = 0;
    bool light_medium = false;
    bool eye_medium = false;
    // P-B2D at either vertex: the eye vertex's own VcmMis::query_beam_factor, and for the light
    // vertex (the connection segment as the query) VcmMis::query_beam_term of the eye vertex's
    // density of it without the distance density. 0: no P-B2D there.
    float eye_query_beam = 0;
    float light_query_beam = 0;
    // Joint (J1) connections (bpt --joint-connections on, docs/design/media.md): the density of the
    // J1 technique of a junction over that of the plain connection of the same junction (0 where
    // there is no J1 technique). light_joint_ratio: the junction one step toward the light (its
    // eye-side vertex is the light vertex, sampled from the eye vertex); joint_ratio: this
    // junction.
    float light_joint_ratio = 0;
    float joint_ratio = 0;
    // Joint (J2) connections (bpt --joint-connections j2|all): the density of a junction's J2
    // technique over that of its J1 technique, q = p_B2 / p_distance of the light-side vertex
    // (0 where there is no J2 technique): light_joint2_ratio for the junction one step toward the
    // light, joint2_ratio for this one; eye_joint2 the junction one step toward the camera
    // (VcmMis::eye_joint2_term).
    float light_joint2_ratio = 0;
    float joint2_ratio = 0;
    float eye_joint2 = 0;
    // B-B1D at either vertex (the connection segment as the query at the light vertex, as the
    // photon beam at the eye vertex): VcmMis::photon_beam_light_term and photon_beam_eye_term.
    float light_photon_beam = 0;
    float eye_photon_beam = 0;
};

// Eq. (46): a light vertex connected to the camera.
struct CameraTechnique {
    // The camera's density of the vertex (area or volume, per unit pixel area).
    float camera_pdf_a = 0;
    // The vertex's density back along the light subpath given the direction to the camera.
    float light_reverse_w = 0;
    bool light_medium = false;
    // P-B2D at the vertex with the camera ray as the query: VcmMis::query_beam_term of the
    // camera's density of the vertex without the distance density, over N_light.
    float light_query_beam = 0;
    // J1 of the junction whose eye-side vertex is the light vertex, sampled from the camera
    // (ConnectionTechnique::light_joint_ratio).
    float light_joint_ratio = 0;
    // J2 of that junction over its J1 (ConnectionTechnique::light_joint2_ratio).
    float light_joint2_ratio = 0;
    // B-B1D at the vertex with the camera ray as the query: VcmMis::photon_beam_light_term of
    // the camera's density of the vertex without the distance density, over N_light.
    float light_photon_beam = 0;
};

// Eqs. (38) and (39): merging an eye vertex with a light vertex.
struct MergeTechnique {
    // The eye vertex's density of continuing toward the light vertex's predecessor, and back
    // along the eye subpath.
    float eye_forward_w = 0;
    float eye_reverse_w = 0;
    bool medium = false;  // both vertices are in a medium (otherwise both at surfaces)
    // A point merge in a medium: the eye vertex's VcmMis::query_beam_factor (P-B2D at the same
    // vertex), 0 without query beams.
    float query_beam = 0;
    // B-B1D at the same vertex: VcmMis::photon_beam_merge_term for a point merge, and
    // photon_beam_light_term(sin, 1, ...) (the factor times the camera side's distance density)
    // for a query beam. 0 without photon beams.
    float photon_beam = 0;
    // J1 (vcm --joint-connections on) of the junction whose eye-side vertex is the merge vertex:
    // its density over the plain connection's there, the vertex sampled from the eye's previous
    // vertex toward the light vertex's predecessor (ConnectionTechnique::light_joint_ratio);
    // 0 where that junction has no J1 technique.
    float light_joint_ratio = 0;
};

// Which techniques a VcmMis combines, by their merging ratios (0: the technique is off).
struct MisTechniques {
    bool connections = true;    // every connection technique (s, t)
    double surface_eta = 0;     // merging at surfaces, pi r^2 N_light
    double point_eta = 0;       // photon points in media (P-P3D), 4/3 pi r^3 N_light
    double query_beam_eta = 0;  // photon points along camera segments (P-B2D), pi r_2^2 N_light
    // Photon beams gathered by camera segments (B-B1D): eta_1 N_light, with eta_1 = r_1 / 2
    // (SmallUPBP's constant) or 2 r_1 (the kernel's support); 0: off.
    double photon_beam_eta = 0;
    // Short photon beams (each ends at its light subpath's sampled distance) instead of long
    // ones (each reaches the next surface).
    bool short_photon_beams = false;
};

class VcmMis {
  public:
    // use_vc / use_vm select the enabled technique families; eta_vcm = pi r^2 N_light (the
    // report's ratio between merging and connection densities at a surface vertex);
    // eta_vcm_volume = 4/3 pi r^3 N_light, the same at a medium vertex (0: as at surfaces);
    // light_path_count = N_light, the number of light subpaths per iteration.
    VcmMis(int power, bool use_vc, bool use_vm, double eta_vcm, double light_path_count,
           double eta_vcm_volume = 0)
        : VcmMis(power,
                 MisTechniques{
                     .connections = use_vc,
                     .surface_eta = use_vm ? eta_vcm : 0.0,
                     .point_eta = use_vm ? (eta_vcm_volume > 0 ? eta_vcm_volume : eta_vcm) : 0.0},
                 light_path_count) {}

    VcmMis(int power, const MisTechniques& techniques, double light_path_count)
        : power_(power),
          use_vc_(techniques.connections),
          light_path_count_(float(light_path_count)) {
        // Clamped so that an extreme radius (at the floor of the schedule) cannot turn the
        // factors into infinities and the weights into NaN.
        const double etas[2] = {techniques.surface_eta, techniques.point_eta};
        for (int m = 0; m < 2; ++m) {
            vm_weight_factor_[m] = etas[m] > 0 ? clamp_factor(mis_double(etas[m])) : 0.0f;
            inverse_eta_[m] = etas[m] > 0 ? clamp_factor(mis_double(1.0 / etas[m])) : 0.0f;
            vc_weight_factor_[m] = use_vc_ ? inverse_eta_[m] : 0.0f;
        }
        if (techniques.query_beam_eta > 0) {
            query_beam_eta_mis_ = mis_double(techniques.query_beam_eta);
            inverse_query_beam_ = clamp_factor(1.0 / query_beam_eta_mis_);
        }
        if (techniques.photon_beam_eta > 0) {
            photon_beam_eta_mis_ = mis_double(techniques.photon_beam_eta);
            short_photon_beams_ = techniques.short_photon_beams;
        }
    }

    float mis(float p) const { return power_ == 1 ? p : p * p; }
    // Merging relative to connection at a vertex (surface, or medium when `medium`).
    float vm_weight_factor(bool medium = false) const { return vm_weight_factor_[medium]; }
    float vc_weight_factor(bool medium = false) const { return vc_weight_factor_[medium]; }

    // Eqs. (31)-(33): a light subpath starting at a light with the given densities (the light
    // selection probability included). cos_light is 1 for infinite lights.
    MisQuantities start_light(float direct_pdf_a, float emission_pdf_w, float cos_light,
                              bool delta_light) const {
        MisQuantities q;
        q.dVCM = mis(direct_pdf_a / emission_pdf_w);
        q.dVC = delta_light ? 0.0f : mis(cos_light / emission_pdf_w);
        q.dVM = use_vc_ ? q.dVC : 0.0f;
        return q;
    }

    // Eqs. (31)-(33) for the eye: the pinhole is a delta point, so only dVCM is set.
    // camera_pdf_w is the camera's solid-angle density per unit pixel area.
    MisQuantities start_camera(float camera_pdf_w) const {
        MisQuantities q;
        q.dVCM = camera_pdf_w > 0 ? mis(light_path_count_ / camera_pdf_w) : 0.0f;
        return q;
    }

    // Eqs. (34)-(36), second half: completes the conversion of the segment just traced to the
    // new vertex's measure. dist2: its squared length (apply_distance = false for the first
    // segment from an infinite light, and for a path leaving the scene); cos_in: |cos| at the new
    // vertex (1 in a medium). Through media the density of the new vertex also carries the
    // distance sampling: forward_distance is that density (per unit length at a medium vertex,
    // the probability of passing every medium on the way at a surface), reverse_distance the
    // same for sampling the segment's start from its end (core/integrators/medium_segment.h).
    void arrive(MisQuantities& q, float dist2, bool apply_distance, float cos_in,
                float forward_distance = 1.0f, float reverse_distance = 1.0f) const {
        if (apply_distance) q.dVCM *= mis(dist2);
        const float c = mis(cos_in * forward_distance);
        const float r = mis(reverse_distance);
        q.dVCM /= c;
        q.dVC *= r / c;
        q.dVM *= r / c;
    }

    // Eqs. (34)-(36), first half: leaving a vertex in a sampled direction with |cos| = cos_out
    // (1 in a medium), forward density forward_w and reverse density reverse_w. At a specular
    // vertex the two (then discrete lobe probabilities) are equal and cancel, and no technique
    // ends there, so dVCM becomes 0. `medium`: the vertex is in a medium (merging there uses
    // photon points). query_beam: the vertex's own query_beam_factor (eye subpaths; light
    // subpaths add theirs later, add_query_beam_term).
    void scatter(MisQuantities& q, float cos_out, float forward_w, float reverse_w, bool specular,
                 bool medium = false, float query_beam = 0) const {
        if (specular) {
            q.dVCM = 0;
            q.dVC *= mis(cos_out);
            q.dVM *= mis(cos_out);
            return;
        }
        const float g = mis(cos_out / forward_w);
        const float vm = vm_weight_factor_[medium] + query_beam;
        q.dVC = g * (q.dVC * mis(reverse_w) + q.dVCM + vm);
        q.dVM = g * (q.dVM * mis(reverse_w) + (use_vc_ ? q.dVCM : 0.0f) + vm);
        q.dVCM = mis(1.0f / forward_w);
    }

    // P-B2D (query beams). Whether the technique is on.
    bool uses_query_beams() const { return query_beam_eta_mis_ > 0; }
    // The merge factor of P-B2D at a medium vertex whose camera-side distance density (per unit
    // length, the whole segment's as SegmentDensities gives it) is camera_distance_l:
    // mis(eta_2D / camera_distance_l); 0 without query beams.
    float query_beam_factor(float camera_distance_l) const {
        if (!uses_query_beams()) return 0.0f;
        return clamp_factor(query_beam_eta_mis_ / mis_double(camera_distance_l));
    }
    // The P-B2D term of a vertex as seen from a technique that samples it from the camera side
    // with density p (the distance density already left out of p): mis(eta_2D p). Formed
    // here so that the distance density is never divided out after being multiplied in.
    float query_beam_term(float pdf_without_distance) const {
        if (!uses_query_beams()) return 0.0f;
        return clamp_factor(query_beam_eta_mis_ * mis_double(pdf_without_distance));
    }
    // Light subpaths: at a medium vertex, the factor g that scatter() applies, kept so that the
    // vertex's P-B2D term can be added at the next arrival (0 without query beams).
    float carried_query_beam_term(float cos_out, float forward_w, bool specular) const {
        if (!uses_query_beams() || specular || !(forward_w > 0)) return 0.0f;
        return mis(cos_out / forward_w);
    }
    // After arrive(): the P-B2D term of the vertex the segment started at. arrive() multiplied
    // its terms by mis(p_t), p_t being the camera side's distance density of that vertex, which
    // is exactly what the factor mis(eta_2D / p_t) divides out.
    void add_query_beam_term(MisQuantities& q, float carried, float cos_in,
                             float forward_distance) const {
        if (!(carried > 0)) return;
        const float term =
            clamp_factor(carried * query_beam_eta_mis_ / mis_double(cos_in * forward_distance));
        q.dVC += term;
        q.dVM += term;
    }

    // B-B1D (photon beams; ALGORITHMS-NEXT.md 4.3, docs/design/media.md "Photon beams"). A light
    // segment x_{i-1} -> x_i in a medium is a photon beam, the camera segment x_{i+1} -> x_i
    // the query; neither samples the distance to x_i. Relative to a point merge at x_i the
    // technique's density has the merge factor
    //     M_B(x_i) = eta_1 N sin(theta) q_L / p_C,
    // theta the angle between the two segments, p_C the camera side's distance density of x_i
    // (the query is long: it covers x_i whatever the eye sampled), q_L = 1 / p_L for a long
    // photon beam (p_L the light side's distance density of x_i) and 1 / sigma_t(x_i) for a
    // short one (it covers x_i with probability P_pass, and P_pass / p_L = 1 / sigma_t: exact
    // for grey homogeneous media, a proxy with the right support otherwise, ALGORITHMS-NEXT.md
    // 0.3). Each subpath knows its own side's density of a vertex on arrival and the other
    // side's one vertex later, where arrive() multiplies it in: so the term of x_i is carried
    // from scatter() at x_i and added after the next arrival (carried_photon_beam_term,
    // add_photon_beam_term), with the density that arrive() multiplies in cancelled
    // symbolically. Every function takes sin(theta) = 0 where the technique cannot sample the
    // vertex (not in a homogeneous medium, the light segment not beam-supported) and treats
    // near-parallel segments (beams_parallel) the same way, as the estimator rejects them.
    bool uses_photon_beams() const { return photon_beam_eta_mis_ > 0; }
    bool short_photon_beams() const { return short_photon_beams_; }
    // The guard of both the estimator and the weights: sin^2(theta) below 1e-5 (SmallUPBP's
    // test), and NaN.
    static bool beams_parallel(float sin_theta) { return !(sin_theta * sin_theta >= 1e-5f); }
    // A vertex's own part of its deferred term: on a light subpath mis(eta_1 N q_L) from the
    // arrival's distance density light_distance (0 if the arrival is not beam-supported); on an
    // eye subpath mis(eta_1 N / p_C), and with short beams also / sigma_t.
    float photon_beam_light_factor(float light_distance, float sigma_t) const {
        if (!uses_photon_beams()) return 0.0f;
        return clamp_factor(photon_beam_eta_mis_ * mis_double(q_light(light_distance, sigma_t)));
    }
    float photon_beam_eye_factor(float camera_distance, float sigma_t) const {
        if (!uses_photon_beams()) return 0.0f;
        const double q =
            1.0 / double(camera_distance) * (short_photon_beams_ ? 1.0 / double(sigma_t) : 1.0);
        return clamp_factor(photon_beam_eta_mis_ * mis_double(q));
    }
    // scatter() at a medium vertex with the given factor: g mis(sin) factor, kept for the next
    // arrival.
    float carried_photon_beam_term(float cos_out, float forward_w, bool specular, float sin_theta,
                                   float factor) const {
        if (!(factor > 0) || specular || !(forward_w > 0) || beams_parallel(sin_theta)) return 0.0f;
        return clamp_factor(double(mis(cos_out / forward_w)) * mis_double(sin_theta) * factor);
    }
    // After arrive(): the term of the vertex the segment started at. Light subpaths: arrive()
    // multiplied in mis(p_C) of that vertex, which its q / p_C divides out: carried / c. Eye
    // subpaths: arrive() multiplied in mis(p_L) (reverse_distance); a long beam's q_L = 1 / p_L
    // divides it out, a short beam's keeps it. `supported`: on eye subpaths, whether the
    // segment just traced (the light's segment into that vertex) can carry a photon beam.
    void add_photon_beam_term(MisQuantities& q, float carried, float cos_in, float forward_distance,
                              float reverse_distance, bool eye_subpath, bool supported) const {
        if (!(carried > 0) || !supported) return;
        double term = double(carried) / mis_double(double(cos_in) * forward_distance);
        if (eye_subpath && short_photon_beams_) term *= mis_double(reverse_distance);
        const float t = clamp_factor(term);
        q.dVC += t;
        q.dVM += t;
    }
    // The term of a light vertex (its arrival's light_distance, sigma_t) in a technique that
    // samples it from the camera side with density pdf_without_distance times p_C:
    // mis(pdf eta_1 N sin q_L) = mis(pdf p_C) mis(M_B) (connections, camera connections; with
    // pdf = 1 a query beam's term).
    float photon_beam_light_term(float sin_theta, float pdf_without_distance, float light_distance,
                                 float sigma_t) const {
        if (!uses_photon_beams() || beams_parallel(sin_theta)) return 0.0f;
        return clamp_factor(photon_beam_eta_mis_ *
                            mis_double(double(pdf_without_distance) * sin_theta *
                                       q_light(light_distance, sigma_t)));
    }
    // The term of an eye vertex (its arrival's camera_distance, sigma_t) in a technique that
    // samples it from the light side with density pdf_with_distance = pdf_without_distance p_L
    // (connections, next-event estimation): mis(pdf_with_distance) mis(M_B), formed without
    // dividing p_L back out for long beams. `supported`: the light side's segment can carry a
    // photon beam.
    float photon_beam_eye_term(float sin_theta, float camera_distance, float sigma_t,
                               float pdf_with_distance, float pdf_without_distance,
                               bool supported) const {
        if (!uses_photon_beams() || !supported || beams_parallel(sin_theta)) return 0.0f;
        const double pdf = short_photon_beams_ ? double(pdf_with_distance) / double(sigma_t)
                                               : double(pdf_without_distance);
        return clamp_factor(photon_beam_eta_mis_ *
                            mis_double(pdf * sin_theta / double(camera_distance)));
    }
    // mis(M_B) of a vertex merged as a point (MergeTechnique::photon_beam): the light vertex's
    // arrival density light_distance (0: not beam-supported), the eye vertex's camera_distance.
    float photon_beam_merge_term(float sin_theta, float light_distance, float camera_distance,
                                 float sigma_t) const {
        if (!uses_photon_beams() || beams_parallel(sin_theta) || !(light_distance > 0)) return 0.0f;
        return clamp_factor(photon_beam_eta_mis_ *
                            mis_double(double(sin_theta) * q_light(light_distance, sigma_t) /
                                       double(camera_distance)));
    }

    // Joint (J1) connections. A J1 technique samples the eye-side vertex x_j of junction j (a
    // medium vertex) by half-line equi-angular sampling toward the light-side vertex x_{j-1} (a
    // scattering vertex, or at j = 1 a finite light's point: next-event estimation's sibling,
    // DirectTechnique::joint_ratio) instead of by distance sampling; its density is the
    // connection's times r_j = p_eq(x_j) / p_distance(x_j), so every connection term of the
    // recursion is multiplied by (1 + mis(r_j)). Eye subpaths know r_j of the junction toward the
    // camera when they arrive at a vertex (include_joint_junction); light subpaths know it one
    // vertex later, so the term a scatter adds (carried_connection_term) is kept aside and
    // completed at the next arrival (add_joint_term). With merging (vcm) the J1 terms count in the
    // merge weights like the connection terms they multiply: dVM holds the same connection terms as
    // dVC (add_joint_term adds to both), and weight_merge takes the one junction's factor that
    // neither subpath holds (MergeTechnique::light_joint_ratio; docs/design/media.md).
    void include_joint_junction(MisQuantities& q, float joint_ratio) const {
        q.dVCM *= 1.0f + mis(joint_ratio);
    }
    // The connection term that scatter() is about to add to dVC, as arrive() will scale it.
    float carried_connection_term(const MisQuantities& q, float cos_out, float forward_w,
                                  bool specular) const {
        return specular || !(forward_w > 0) ? 0.0f : mis(cos_out / forward_w) * q.dVCM;
    }
    // After arrive(): the J1 technique of the junction whose eye-side vertex is the one the
    // segment started at, with joint_pdf_l its equi-angular density there (arrive() gave the
    // plain connection the reverse distance density instead).
    // joint2_ratio: that junction's J2 over its J1 (0: none), whose term rides on J1's.
    void add_joint_term(MisQuantities& q, float carried, float joint_pdf_l, float cos_in,
                        float forward_distance, float joint2_ratio = 0) const {
        const float term = carried * mis(joint_pdf_l) * (1.0f + mis(joint2_ratio)) /
                           mis(cos_in * forward_distance);
        q.dVC += term;
        if (use_vc_) q.dVM += term;  // connection terms count in merge weights (scatter())
    }

    // Joint (J2) connections, the segment-segment connection (docs/design/media.md): junction j's
    // J2 technique samples its light-side vertex x_{j-1} on the light ray from x_{j-2} by B2
    // (joint_light_distance.h) and then x_j like J1; its density is J1's times
    // q_j = p_B2(x_{j-1}) / p_distance(x_{j-1}), so each connection term gets
    // (1 + mis(r_j) (1 + mis(q_j))). q_j needs x_{j-2} .. x_{j+1}: light subpaths complete it with
    // J1's deferred term (add_joint_term's joint2_ratio); a connection takes it for its own
    // junction and the one toward the light (ConnectionTechnique, CameraTechnique); eye subpaths
    // know the part of the junction toward the camera that J1 folded into dVCM, and its q only
    // when the next light-side vertex is known: at a connection or next-event estimation
    // (eye_joint2_term), or, carried from a scatter (carried_eye_joint2_term), at the next
    // arrival (add_eye_joint2_term).
    //
    // The eye vertex's share of dVCM that is the J1 technique of the junction toward the camera
    // (include_joint_junction multiplied dVCM by 1 + mis(r)), times mis(q) of that junction's J2.
    float eye_joint2_term(const MisQuantities& eye, float joint_ratio, float joint2_ratio) const {
        if (!(joint_ratio > 0) || !(joint2_ratio > 0)) return 0.0f;
        const float j1 = mis(joint_ratio);
        return eye.dVCM * (j1 / (1.0f + j1)) * mis(joint2_ratio);
    }
    // Eye subpaths: the J1 share above as scatter() is about to carry it into dVC.
    float carried_eye_joint2_term(const MisQuantities& eye, float joint_ratio, float cos_out,
                                  float forward_w, bool specular) const {
        if (!(joint_ratio > 0) || specular || !(forward_w > 0)) return 0.0f;
        const float j1 = mis(joint_ratio);
        return mis(cos_out / forward_w) * eye.dVCM * (j1 / (1.0f + j1));
    }
    // After arrive() on an eye subpath: the J2 technique of the junction two steps back (the
    // vertex the segment left is its light-side vertex, sampled from the new vertex by B2 with
    // density joint2_pdf_l; arrive() gave the plain connection the reverse distance density).
    void add_eye_joint2_term(MisQuantities& q, float carried, float joint2_pdf_l, float cos_in,
                             float forward_distance) const {
        if (!(carried > 0) || !(joint2_pdf_l > 0)) return;
        const float term = carried * mis(joint2_pdf_l) / mis(cos_in * forward_distance);
        q.dVC += term;
        if (use_vc_) q.dVM += term;
    }

    // Eq. (43): the eye subpath hit an emitter. direct_pdf_a and emission_pdf_w include the
    // light selection probability. joint_ratio: J1 at s = 1 of the eye vertex before the hit
    // point (DirectTechnique::joint_ratio; 0: none), which multiplies next-event estimation's
    // term as J1 multiplies every connection term.
    float weight_emission(const MisQuantities& eye, float direct_pdf_a, float emission_pdf_w,
                          float joint_ratio = 0) const {
        const float w_camera = mis(direct_pdf_a) * eye.dVCM * (1.0f + mis(joint_ratio)) +
                               mis(emission_pdf_w) * eye.dVC;
        return 1.0f / (1.0f + w_camera);
    }

    // Eqs. (44) and (45): next-event estimation (DirectTechnique above).
    float weight_direct(const MisQuantities& eye, const DirectTechnique& t) const {
        const float w_light =
            t.delta_light ? 0.0f
                          : mis(t.bsdf_forward_w * t.pass_to_light_probability / t.light_pdf_w);
        const float w_camera =
            t.cos_light > 0 ? mis(t.emission_pdf_w * t.cos_here * t.distance_from_light /
                                  (t.direct_pdf_w * t.cos_light)) *
                                      (vm_weight_factor_[t.eye_medium] + t.eye_query_beam +
                                       eye.dVCM + t.eye_joint2 + eye.dVC * mis(t.bsdf_reverse_w)) +
                                  t.eye_photon_beam
                            : 0.0f;
        return 1.0f / (w_light + 1.0f + mis(t.joint_ratio) + w_camera);
    }

    // J1 at s = 1: the receiver sampled toward the light point (next-event estimation's sibling).
    float weight_joint_direct(const MisQuantities& eye, const DirectTechnique& t) const {
        return mis(t.joint_ratio) * weight_direct(eye, t);
    }

    // Eqs. (40) and (41): connecting an eye vertex to a light vertex (ConnectionTechnique).
    float weight_connection(const MisQuantities& light, const MisQuantities& eye,
                            const ConnectionTechnique& t) const {
        const float w_light = mis(t.eye_pdf_a) * (vm_weight_factor_[t.light_medium] +
                                                  light.dVCM * joint_factor(t.light_joint_ratio,
                                                                            t.light_joint2_ratio) +
                                                  light.dVC * mis(t.light_reverse_w)) +
                              t.light_query_beam + t.light_photon_beam;
        const float w_camera =
            mis(t.light_pdf_a) * (vm_weight_factor_[t.eye_medium] + t.eye_query_beam + eye.dVCM +
                                  t.eye_joint2 + eye.dVC * mis(t.eye_reverse_w)) +
            t.eye_photon_beam;
        // Summed in the order of the J1-only form, so that images without J2 stay bit-identical.
        return 1.0f /
               (w_light + 1.0f + mis(t.joint_ratio) * (1.0f + mis(t.joint2_ratio)) + w_camera);
    }

    // The J1 technique of the same junction (the eye vertex sampled toward the light vertex).
    float weight_joint_connection(const MisQuantities& light, const MisQuantities& eye,
                                  const ConnectionTechnique& t) const {
        return mis(t.joint_ratio) * weight_connection(light, eye, t);
    }

    // The J2 technique of the same junction (both vertices sampled jointly, B2 then J1).
    float weight_joint2_connection(const MisQuantities& light, const MisQuantities& eye,
                                   const ConnectionTechnique& t) const {
        return mis(t.joint_ratio) * mis(t.joint2_ratio) * weight_connection(light, eye, t);
    }

    // Eq. (46): a light vertex connected to the camera (CameraTechnique).
    float weight_camera(const MisQuantities& light, const CameraTechnique& t) const {
        const float w_light =
            mis(t.camera_pdf_a / light_path_count_) *
                (vm_weight_factor_[t.light_medium] +
                 light.dVCM * joint_factor(t.light_joint_ratio, t.light_joint2_ratio) +
                 light.dVC * mis(t.light_reverse_w)) +
            t.light_query_beam + t.light_photon_beam;
        return 1.0f / (w_light + 1.0f);
    }

    // Eqs. (38) and (39): merging an eye vertex with a light vertex (MergeTechnique).
    float weight_merge(const MisQuantities& light, const MisQuantities& eye,
                       const MergeTechnique& t) const {
        const float vc = vc_weight_factor_[t.medium], inverse_eta = inverse_eta_[t.medium];
        const float w_light = light.dVCM * vc * (1.0f + mis(t.light_joint_ratio)) +
                              light.dVM * inverse_eta * mis(t.eye_forward_w);
        const float w_camera = eye.dVCM * vc + eye.dVM * inverse_eta * mis(t.eye_reverse_w);
        return 1.0f / (w_light + 1.0f + t.query_beam * inverse_eta + t.photon_beam * inverse_eta +
                       w_camera);
    }

    // P-B2D: a photon (light subpath `light`) within r_2 of a camera segment, gathered at its
    // projection on the segment. eye_at_query: the eye subpath's quantities as if it had
    // arrived at the projection, from arrive() with forward_distance = 1; camera_distance_l:
    // that distance density, applied here (multiplying the other side instead of dividing this
    // one, so that a density that underflows gives the query beam the path, not a NaN).
    // t.eye_*_w: the phase function at the photon with the query's direction as the eye's.
    float weight_query_beam(const MisQuantities& light, const MisQuantities& eye_at_query,
                            float camera_distance_l, const MergeTechnique& t) const {
        const float connections = use_vc_ ? 1.0f : 0.0f;
        const float light_side =
            vm_weight_factor_[1] + light.dVCM * connections + light.dVM * mis(t.eye_forward_w);
        const float camera_side =
            eye_at_query.dVCM * connections + eye_at_query.dVM * mis(t.eye_reverse_w);
        return 1.0f / (1.0f + (mis(camera_distance_l) * light_side + camera_side + t.photon_beam) *
                                  inverse_query_beam_);
    }

    // B-B1D: a photon beam passing within r_1 of a camera segment (the query), gathered at
    // their closest approach x with sin(theta) between them. light_at_x, eye_at_x: each
    // subpath's quantities as if it had arrived at x (arrive() with forward_distance = 1, the
    // deferred terms added likewise); light_distance and camera_distance: those distance
    // densities p_L, p_C, multiplied into the other terms here instead of divided out (every
    // term below is the technique's ratio times mis(p_L p_C)). t.eye_*_w: the phase function at
    // x with the query as the eye's direction and the beam as the light's.
    float weight_photon_beam(const MisQuantities& light_at_x, const MisQuantities& eye_at_x,
                             float light_distance, float camera_distance, float sin_theta,
                             float sigma_t, const MergeTechnique& t) const {
        if (beams_parallel(sin_theta)) return 0.0f;
        const double connections = use_vc_ ? 1.0 : 0.0;
        const double beam =
            photon_beam_eta_mis_ *
            mis_double(double(sin_theta) *
                       (short_photon_beams_ ? double(light_distance) / sigma_t : 1.0));
        const double p_l = mis_double(light_distance), p_c = mis_double(camera_distance);
        const double light_side = double(light_at_x.dVCM) * connections +
                                  double(light_at_x.dVM) * mis_double(t.eye_forward_w);
        const double camera_side = double(eye_at_x.dVCM) * connections +
                                   double(eye_at_x.dVM) * mis_double(t.eye_reverse_w);
        const double others = p_l * p_c * vm_weight_factor_[1] + p_l * query_beam_eta_mis_ +
                              p_c * light_side + p_l * camera_side;
        const double w = beam / (beam + others);
        return std::isfinite(w) ? float(w) : 0.0f;
    }

  private:
    double mis_double(double p) const { return power_ == 1 ? p : p * p; }
    // A junction's plain connection, J1 and J2 relative to the plain connection.
    float joint_factor(float joint_ratio, float joint2_ratio) const {
        return 1.0f + mis(joint_ratio) * (1.0f + mis(joint2_ratio));
    }
    // q_L of B-B1D: 1 / p_L (long photon beams), 1 / sigma_t (short).
    double q_light(float light_distance, float sigma_t) const {
        return 1.0 / double(short_photon_beams_ ? sigma_t : light_distance);
    }
    static float clamp_factor(double f) { return float(f < 1e30 ? f : 1e30); }

    int power_;
    bool use_vc_;
    float light_path_count_;
    // Index 0: surface vertices; 1: medium vertices.
    float vm_weight_factor_[2] = {0, 0}, vc_weight_factor_[2] = {0, 0}, inverse_eta_[2] = {0, 0};
    // P-B2D: mis(eta_2D) (0: off) and its inverse.
    double query_beam_eta_mis_ = 0;
    float inverse_query_beam_ = 0;
    // B-B1D: mis(eta_1 N) (0: off) and the beam length.
    double photon_beam_eta_mis_ = 0;
    bool short_photon_beams_ = false;
};

}  // namespace render
