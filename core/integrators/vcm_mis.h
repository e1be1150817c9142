#pragma once

// The MIS arithmetic of vertex connection and merging, as pure functions: how the recursive
// partial weights dVCM, dVC and dVM of a subpath start, how they are updated along it, and how
// each technique's weight is computed from them. Equation numbers refer to the technical report
// "Implementing Vertex Connection and Merging" (Georgiev 2012). The integrator
// (vertex_cm.cpp) and the test that checks that the weights of all techniques sampling one
// path sum to one (tests/unit/vcm_mis_test.cpp) use these same functions.
//
// Densities in solid angle (_w) or area (_a); "mis(p)" is p^beta (beta = 2: power heuristic,
// beta = 1: balance heuristic). Russian roulette is not part of any density here: the weights
// only need to sum to one over the techniques, and roulette is compensated in the throughput.

namespace render {

struct MisQuantities {
    float dVCM = 0, dVC = 0, dVM = 0;
};

class VcmMis {
  public:
    // use_vc / use_vm select the enabled technique families; eta_vcm = pi r^2 N_light (the
    // report's ratio between merging and connection densities); light_path_count =
    // N_light, the number of light subpaths per iteration.
    VcmMis(int power, bool use_vc, bool use_vm, double eta_vcm, double light_path_count)
        : power_(power), light_path_count_(float(light_path_count)) {
        // Clamped so that an extreme radius (at the floor of the schedule) cannot turn the
        // factors into infinities and the weights into NaN.
        vm_weight_factor_ = use_vm ? clamp_factor(mis_double(eta_vcm)) : 0.0f;
        vc_weight_factor_ = use_vc ? clamp_factor(mis_double(1.0 / eta_vcm)) : 0.0f;
    }

    float mis(float p) const { return power_ == 1 ? p : p * p; }
    float vm_weight_factor() const { return vm_weight_factor_; }
    float vc_weight_factor() const { return vc_weight_factor_; }

    // Eqs. (31)-(33): a light subpath starting at a light with the given densities (the light
    // selection probability included). cos_light is 1 for infinite lights.
    MisQuantities start_light(float direct_pdf_a, float emission_pdf_w, float cos_light,
                              bool delta_light) const {
        MisQuantities q;
        q.dVCM = mis(direct_pdf_a / emission_pdf_w);
        q.dVC = delta_light ? 0.0f : mis(cos_light / emission_pdf_w);
        q.dVM = q.dVC * vc_weight_factor_;
        return q;
    }

    // Eqs. (31)-(33) for the eye: the pinhole is a delta point, so only dVCM is set.
    // camera_pdf_w is the camera's solid-angle density per unit pixel area.
    MisQuantities start_camera(float camera_pdf_w) const {
        MisQuantities q;
        q.dVCM = camera_pdf_w > 0 ? mis(light_path_count_ / camera_pdf_w) : 0.0f;
        return q;
    }

    // Eqs. (34)-(36), second half: completes the area conversion of the segment just traced,
    // of squared length dist2 (pass apply_distance = false for the first segment from an
    // infinite light), arriving with |cos| = cos_in at the new vertex.
    void arrive(MisQuantities& q, float dist2, bool apply_distance, float cos_in) const {
        if (apply_distance) q.dVCM *= mis(dist2);
        const float c = mis(cos_in);
        q.dVCM /= c;
        q.dVC /= c;
        q.dVM /= c;
    }

    // Eqs. (34)-(36), first half: leaving a vertex in a sampled direction with |cos| = cos_out,
    // forward density pdf_forward and reverse density pdf_reverse. At a specular vertex the two
    // densities are equal and cancel, and no technique ends there, so dVCM becomes 0.
    void scatter(MisQuantities& q, float cos_out, float pdf_forward, float pdf_reverse,
                 bool specular) const {
        if (specular) {
            q.dVCM = 0;
            q.dVC *= mis(cos_out);
            q.dVM *= mis(cos_out);
            return;
        }
        const float g = mis(cos_out / pdf_forward);
        q.dVC = g * (q.dVC * mis(pdf_reverse) + q.dVCM + vm_weight_factor_);
        q.dVM = g * (q.dVM * mis(pdf_reverse) + q.dVCM * vc_weight_factor_ + 1.0f);
        q.dVCM = mis(1.0f / pdf_forward);
    }

    // Eq. (43): the eye subpath hit an emitter. direct_pdf_a and emission_pdf_w include the
    // light selection probability.
    float weight_emission(const MisQuantities& eye, float direct_pdf_a,
                          float emission_pdf_w) const {
        const float w_camera = mis(direct_pdf_a) * eye.dVCM + mis(emission_pdf_w) * eye.dVC;
        return 1.0f / (1.0f + w_camera);
    }

    // Eqs. (44) and (45): next-event estimation. light_pdf_w = selection probability times
    // the light's solid-angle density at the receiver; emission_pdf_w and direct_pdf_w are the
    // light's own densities (the selection probability cancels in their ratio); cos_here is at
    // the receiver, cos_light at the light; bsdf_* are the receiver's densities toward the
    // light (forward) and back along the eye path (reverse).
    float weight_direct(const MisQuantities& eye, float bsdf_forward, float bsdf_reverse,
                        float light_pdf_w, float emission_pdf_w, float direct_pdf_w, float cos_here,
                        float cos_light, bool delta_light) const {
        const float w_light = delta_light ? 0.0f : mis(bsdf_forward / light_pdf_w);
        const float w_camera =
            cos_light > 0 ? mis(emission_pdf_w * cos_here / (direct_pdf_w * cos_light)) *
                                (vm_weight_factor_ + eye.dVCM + eye.dVC * mis(bsdf_reverse))
                          : 0.0f;
        return 1.0f / (w_light + 1.0f + w_camera);
    }

    // Eqs. (40) and (41): connecting an eye vertex to a light vertex. eye_pdf_a: the eye
    // vertex's density of sampling the light vertex (area); light_pdf_a: the reverse; *_reverse
    // are each vertex's densities back along its own subpath given the connection direction.
    float weight_connection(const MisQuantities& light, const MisQuantities& eye, float eye_pdf_a,
                            float light_pdf_a, float light_reverse_w, float eye_reverse_w) const {
        const float w_light =
            mis(eye_pdf_a) * (vm_weight_factor_ + light.dVCM + light.dVC * mis(light_reverse_w));
        const float w_camera =
            mis(light_pdf_a) * (vm_weight_factor_ + eye.dVCM + eye.dVC * mis(eye_reverse_w));
        return 1.0f / (w_light + 1.0f + w_camera);
    }

    // Eq. (46): a light vertex connected to the camera. camera_pdf_a is the camera's density
    // of the vertex (area, per unit pixel area); light_reverse_w the vertex's density back
    // along the light subpath given the direction to the camera.
    float weight_camera(const MisQuantities& light, float camera_pdf_a,
                        float light_reverse_w) const {
        const float w_light = mis(camera_pdf_a / light_path_count_) *
                              (vm_weight_factor_ + light.dVCM + light.dVC * mis(light_reverse_w));
        return 1.0f / (w_light + 1.0f);
    }

    // Eqs. (38) and (39): merging an eye vertex with a light vertex. eye_forward_w: the eye
    // vertex's density of continuing toward the light vertex's predecessor; eye_reverse_w:
    // back along the eye subpath.
    float weight_merge(const MisQuantities& light, const MisQuantities& eye, float eye_forward_w,
                       float eye_reverse_w) const {
        const float w_light = light.dVCM * vc_weight_factor_ + light.dVM * mis(eye_forward_w);
        const float w_camera = eye.dVCM * vc_weight_factor_ + eye.dVM * mis(eye_reverse_w);
        return 1.0f / (w_light + 1.0f + w_camera);
    }

  private:
    double mis_double(double p) const { return power_ == 1 ? p : p * p; }
    static float clamp_factor(double f) { return float(f < 1e30 ? f : 1e30); }

    int power_;
    float light_path_count_;
    float vm_weight_factor_ = 0, vc_weight_factor_ = 0;
};

}  // namespace render
