// The MIS weights of paths whose light end is a point y of an emitting medium (a volume light,
// docs/design/media.md "Emitting media as lights"), in the style of vcm_mis_test (kept in a file of
// its own): fog paths camera -> x_1 -> ... -> x_n -> y, every x_k and y in one homogeneous
// chromatic medium with an isotropic phase function. The subpath recursions run as the
// bidirectional iteration runs them (start_volume_light_mis at y, arrive/scatter with the segment
// densities of a real SegmentDensityBuilder, volume_light_illuminate for next-event estimation),
// and every technique that samples the path gets its weight:
//   s = 0  the eye's collision estimate of the emission at y (volume_emission_weight),
//   s = 1  next-event estimation from x_n to y (weight_direct),
//   s >= 2 connections x_{j-1} - x_j, t = 1 the light subpath x_1 connected to the camera,
//   merges at every x_i (vcm: photon points, eta = 4/3 pi r^3 N).
// Checks, for bpt and vcm, power and balance heuristics, and light selection probabilities 1
// and 0.3 (an area light beside the volume, which takes the rest): the weights sum to one, and
// each equals p_k^beta / sum_j p_j^beta with every technique's density written out directly
// (reference_densities: no recursion).

#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <vector>

#include "core/integrators/bidirectional/vcm_mis.h"
#include "core/integrators/medium_segment.h"
#include "core/integrators/volume_light_sampling.h"
#include "core/math/constants.h"
#include "core/media/homogeneous_medium.h"
#include "core/media/isotropic_phase.h"
#include "core/sampling/rng.h"

namespace render {
namespace {

constexpr float kPhase = kInv4Pi;     // isotropic: both directions' density
constexpr float kCameraPdfW = 2.7f;   // the camera's solid-angle density per pixel area
constexpr float kPdfVolume = 0.21f;   // p_V(y)
constexpr double kLightPaths = 4096;  // N_L
constexpr double kRadius = 0.05;      // merge radius

struct Fog {
    HomogeneousMedium medium{Rgb(0.1f, 0.3f, 0.6f), Rgb(0.4f, 0.5f, 0.3f),
                             std::make_shared<IsotropicPhase>()};
    // The integrator's densities of one piece of length d (SegmentDensityBuilder).
    SegmentDensities segment(float d, bool start_in_medium, bool end_in_medium) const {
        SegmentDensityBuilder b(start_in_medium);
        b.add_piece(&medium, Ray(Vec3(0.0f), Vec3(0, 0, 1)), d);
        return b.finish(end_in_medium);
    }
    float scatter(float d) const { return medium.pdf_scatter_l(Ray(Vec3(0.0f), Vec3(0, 0, 1)), d); }
};

struct Case {
    int power;
    bool merging;
    float pick;  // the volume light's selection probability
};

// x[0] the camera, x[1..n] medium vertices, x[n + 1] = y.
std::vector<Vec3> random_path(int n, Rng& rng) {
    std::vector<Vec3> x(size_t(n) + 2);
    for (Vec3& p : x) p = Vec3(rng.next_1d(), rng.next_1d(), rng.next_1d()) * 2.0f;
    return x;
}

float dist(const Vec3& a, const Vec3& b) {
    return length(a - b);
}

// Densities written out: eye and light densities of every vertex (volume measure), then one
// density per technique: T_s for s = 0..n+1 (s = n+1 is t = 1), then M_i for i = 1..n.
std::vector<double> reference_densities(const std::vector<Vec3>& x, const Fog& fog, const Case& c) {
    const int n = int(x.size()) - 2;
    std::vector<double> eye(x.size(), 0.0), light(x.size(), 0.0);
    for (int k = 1; k <= n + 1; ++k) {
        const double d = dist(x[size_t(k)], x[size_t(k - 1)]);
        eye[size_t(k)] = (k == 1 ? kCameraPdfW : kPhase) * fog.scatter(float(d)) / (d * d);
    }
    light[size_t(n + 1)] = double(c.pick) * kPdfVolume;
    for (int k = n; k >= 1; --k) {
        const double d = dist(x[size_t(k)], x[size_t(k + 1)]);
        light[size_t(k)] = kPhase * fog.scatter(float(d)) / (d * d);  // direction 1/4pi at y too
    }
    std::vector<double> p;
    for (int s = 0; s <= n + 1; ++s) {
        double q = s == n + 1 ? kLightPaths : 1.0;
        for (int k = 1; k <= n + 1 - s; ++k) q *= eye[size_t(k)];
        for (int k = n + 2 - s; k <= n + 1; ++k) q *= light[size_t(k)];
        p.push_back(q);
    }
    if (c.merging) {
        const double eta = 4.0 / 3.0 * kPi * kRadius * kRadius * kRadius * kLightPaths;
        for (int i = 1; i <= n; ++i) {
            double q = eta;
            for (int k = 1; k <= i; ++k) q *= eye[size_t(k)];
            for (int k = i; k <= n + 1; ++k) q *= light[size_t(k)];
            p.push_back(q);
        }
    }
    return p;
}

// The same techniques' weights from the recursions, in the same order.
std::vector<double> recursive_weights(const std::vector<Vec3>& x, const Fog& fog, const Case& c) {
    const int n = int(x.size()) - 2;
    const double eta = 4.0 / 3.0 * kPi * kRadius * kRadius * kRadius * kLightPaths;
    const VcmMis mis(
        c.power,
        MisTechniques{.connections = true,
                      .surface_eta = c.merging ? kPi * kRadius * kRadius * kLightPaths : 0.0,
                      .point_eta = c.merging ? eta : 0.0},
        kLightPaths);
    // Light subpath: y, x_n, ..., x_1 (L[k]: at x_k after arriving).
    std::vector<MisQuantities> L(x.size()), E(x.size());
    MisQuantities q = start_volume_light_mis(mis, c.pick * kPdfVolume);
    for (int k = n; k >= 1; --k) {
        const float d = dist(x[size_t(k)], x[size_t(k + 1)]);
        const SegmentDensities s = fog.segment(d, true, true);
        mis.arrive(q, d * d, true, 1.0f, s.toward_end, s.toward_start);
        L[size_t(k)] = q;
        mis.scatter(q, 1.0f, kPhase, kPhase, false, true);
    }
    // Eye subpath: camera, x_1, ..., x_{n+1} = y.
    q = mis.start_camera(kCameraPdfW);
    for (int k = 1; k <= n + 1; ++k) {
        const float d = dist(x[size_t(k)], x[size_t(k - 1)]);
        const SegmentDensities s = fog.segment(d, k > 1, true);
        mis.arrive(q, d * d, true, 1.0f, s.toward_end, s.toward_start);
        E[size_t(k)] = q;
        if (k <= n) mis.scatter(q, 1.0f, kPhase, kPhase, false, true);
    }
    std::vector<double> w;
    // s = 0.
    w.push_back(volume_emission_weight(mis, E[size_t(n + 1)], c.pick * kPdfVolume));
    // s = 1: next-event estimation from x_n, as direct_contribution forms it from the sample.
    {
        LightIlluminateSample ls;
        EXPECT_TRUE(
            volume_light_illuminate(x[size_t(n)], x[size_t(n + 1)], Rgb(1.0f), kPdfVolume, ls));
        const SegmentDensities l = fog.segment(ls.distance, true, true);
        w.push_back(mis.weight_direct(E[size_t(n)],
                                      DirectTechnique{.bsdf_forward_w = kPhase,
                                                      .bsdf_reverse_w = kPhase,
                                                      .light_pdf_w = c.pick * ls.pdf_direct_w,
                                                      .emission_pdf_w = ls.pdf_emission_w,
                                                      .direct_pdf_w = ls.pdf_direct_w,
                                                      .cos_here = 1.0f,
                                                      .cos_light = ls.cos_at_light,
                                                      .delta_light = false,
                                                      .eye_medium = true,
                                                      .pass_to_light_probability = l.toward_end,
                                                      .distance_from_light = l.toward_start}));
    }
    // 2 <= s <= n: light vertex x_j, eye vertex x_{j-1}.
    for (int s = 2; s <= n; ++s) {
        const int j = n + 2 - s;
        const float d = dist(x[size_t(j)], x[size_t(j - 1)]);
        const SegmentDensities l = fog.segment(d, true, true);
        w.push_back(mis.weight_connection(
            L[size_t(j)], E[size_t(j - 1)],
            ConnectionTechnique{.eye_pdf_a = kPhase * l.toward_end / (d * d),
                                .light_pdf_a = kPhase * l.toward_start / (d * d),
                                .light_reverse_w = kPhase,
                                .eye_reverse_w = kPhase,
                                .light_medium = true,
                                .eye_medium = true}));
    }
    // t = 1: x_1 to the camera.
    {
        const float d = dist(x[1], x[0]);
        const SegmentDensities l = fog.segment(d, true, false);
        w.push_back(mis.weight_camera(
            L[1], CameraTechnique{.camera_pdf_a = kCameraPdfW * l.toward_start / (d * d),
                                  .light_reverse_w = kPhase,
                                  .light_medium = true}));
    }
    if (c.merging)
        for (int i = 1; i <= n; ++i)
            w.push_back(mis.weight_merge(
                L[size_t(i)], E[size_t(i)],
                MergeTechnique{.eye_forward_w = kPhase, .eye_reverse_w = kPhase, .medium = true}));
    return w;
}

TEST(VolumeEmitterMis, WeightsSumToOneAndEqualTheWrittenDensities) {
    const Fog fog;
    Rng rng(StreamKey{5, 0, 1, 0});
    int checked = 0;
    for (const Case c : {Case{2, false, 1.0f}, Case{1, false, 1.0f}, Case{2, true, 1.0f},
                         Case{1, true, 1.0f}, Case{2, false, 0.3f}, Case{2, true, 0.3f}}) {
        for (int n = 1; n <= 4; ++n)
            for (int trial = 0; trial < 20; ++trial) {
                const std::vector<Vec3> x = random_path(n, rng);
                const std::vector<double> p = reference_densities(x, fog, c);
                const std::vector<double> w = recursive_weights(x, fog, c);
                ASSERT_EQ(p.size(), w.size());
                double total = 0, sum = 0;
                for (double pk : p) total += c.power == 2 ? pk * pk : pk;
                for (double wk : w) sum += wk;
                SCOPED_TRACE("power " + std::to_string(c.power) + (c.merging ? " vcm" : " bpt") +
                             " pick " + std::to_string(c.pick) + " n " + std::to_string(n));
                EXPECT_NEAR(sum, 1.0, 1e-4);
                for (size_t k = 0; k < p.size(); ++k) {
                    const double expected = (c.power == 2 ? p[k] * p[k] : p[k]) / total;
                    EXPECT_NEAR(w[k], expected, 1e-4 + 1e-3 * expected) << "technique " << k;
                }
                ++checked;
            }
    }
    EXPECT_EQ(checked, 6 * 4 * 20);
}

}  // namespace
}  // namespace render
