#include "core/integrators/bidirectional/iteration_plan.h"

#include <algorithm>
#include <climits>
#include <cmath>

#include "core/integrators/merge_radius.h"
#include "core/math/constants.h"
#include "core/scene/scene.h"

namespace render::bidirectional {

namespace {

// The path length and light path count every plan shares.
void plan_subpaths(IterationPlan& p, const SubpathSettings& s, const Scene& scene) {
    p.max_length = s.max_depth < 0 ? INT_MAX / 4 : s.max_depth;
    p.rr_depth = s.rr_depth;
    p.roulette = s.roulette;
    p.pixel_count = uint64_t(scene.camera().width()) * uint64_t(scene.camera().height());
    p.light_path_count = s.light_path_count > 0 ? s.light_path_count : p.pixel_count;
    p.vpl_scale = float(1.0 / double(p.light_path_count));
}

}  // namespace

IterationPlan plan_iteration(const BidirectionalConfig& config, const Scene& scene,
                             uint64_t iteration) {
    using A = BidirectionalAlgorithm;
    const A a = config.algorithm;
    const UpbpSettings& upbp = config.upbp;
    const bool is_upbp = a == A::Upbp;
    IterationPlan p;
    plan_subpaths(p, config.subpaths, scene);
    p.light_tracing_only = a == A::LightTracing;
    p.ppm = a == A::Ppm;
    p.ic_connections = a == A::Bpt && config.ic_connections.enabled;
    p.vertex_connections = a == A::Bpt || a == A::Vcm || (is_upbp && upbp.vertex_connections);
    p.merging = a == A::Ppm || a == A::Bpm || a == A::Vcm || is_upbp;
    p.merge_surfaces = p.merging && (!is_upbp || upbp.surface_merging);
    p.merge_points = p.merging && (!is_upbp || upbp.photon_points);
    p.query_beams = is_upbp && upbp.query_beams && scene.has_media();
    p.photon_beams = is_upbp && upbp.photon_beams && scene.has_media();
    p.short_photon_beams = upbp.short_photon_beams;
    // Not beside upbp's beams, whose weights have no J1 factors, nor beside emitting media.
    p.joint = (a == A::Bpt || a == A::Vcm) && config.joint.j1 && p.vertex_connections &&
              !p.ic_connections && scene.has_media() && scene.volume_lights().empty();
    p.joint2 = p.joint && config.joint.j2 && a == A::Bpt;

    const double scene_radius = scene.bounding_sphere().radius;
    const double r1 =
        initial_merge_radius(config.merging.radius_factor, config.merging.radius_pixels,
                             scene.camera(), scene.bounding_sphere());
    p.radius = merge_radius(r1, config.merging.alpha, iteration);
    // UPBP's volume estimators have their own schedule, reduced as their kernels' dimensions
    // ask (3 for photon points, 2 for query beams); without one, photon points merge with the
    // surfaces' radius, and query beams share it too (a disc, like a surface merge).
    const bool volume_schedule = upbp.volume_radius_factor > 0;
    p.volume_radius = volume_schedule ? merge_radius_in(upbp.volume_radius_factor * scene_radius,
                                                        upbp.volume_alpha, iteration, 3)
                                      : p.radius;
    p.beam_radius = volume_schedule ? merge_radius_in(upbp.volume_radius_factor * scene_radius,
                                                      upbp.volume_alpha, iteration, 2)
                                    : p.radius;
    // Photon beams: a 1-D kernel, r_i = r_1 i^(alpha - 1) (merge_radius_in at dimension 1) on
    // the volume schedule, else on the surfaces' factor and alpha.
    p.photon_beam_radius =
        merge_radius_in(volume_schedule ? upbp.volume_radius_factor * scene_radius : r1,
                        volume_schedule ? upbp.volume_alpha : config.merging.alpha, iteration, 1);
    const double n_light = double(p.light_path_count);
    const double eta_vcm = kPi * p.radius * p.radius * n_light;
    // Photon points in media: the kernel is a ball, eta = 4/3 pi r^3 N_light.
    const double eta_vcm_volume =
        4.0 / 3.0 * kPi * p.volume_radius * p.volume_radius * p.volume_radius * n_light;
    // The light paths whose photon points query beams gather: the first K of N_L (K =
    // ceil(fraction N_L), at least 1), an unbiased subset as for photon beams below.
    auto path_subset = [&](double fraction) -> uint64_t {
        if (!(fraction < 1)) return p.light_path_count;
        const double k = std::ceil(fraction * n_light);
        return std::clamp<uint64_t>(k >= 1 ? uint64_t(k) : 1, 1, p.light_path_count);
    };
    p.query_beam_path_count =
        p.query_beams ? path_subset(upbp.query_beam_paths) : p.light_path_count;
    // Query beams: the kernel is a disc around the camera segment, eta = pi r^2 K.
    const double eta_beam = kPi * p.beam_radius * p.beam_radius * double(p.query_beam_path_count);
    p.vm_normalization = float(1.0 / eta_vcm);
    p.vm_normalization_volume = float(1.0 / eta_vcm_volume);
    p.beam_normalization = float(1.0 / eta_beam);
    // Photon beams come from the first K of the N_L light paths (K = ceil(fraction N_L), at
    // least 1): each of those K paths' beams is one sample of B-B1D, so its normalisation and
    // its eta count K, where every other estimator counts N_L. The paths are independent and
    // identically distributed, so any fixed K of them are an unbiased subset.
    p.photon_beam_path_count =
        p.photon_beams ? path_subset(upbp.photon_beam_paths) : p.light_path_count;
    const double n_beam = double(p.photon_beam_path_count);
    // The box kernel 1 / (2 r_1), each of the K light paths' beams one sample.
    p.photon_beam_normalization = float(1.0 / (2.0 * p.photon_beam_radius * n_beam));
    p.mis_power = config.mis_power;
    p.mis_techniques = MisTechniques{
        .connections = p.vertex_connections,
        .surface_eta = p.merge_surfaces ? eta_vcm : 0.0,
        .point_eta = p.merge_points ? eta_vcm_volume : 0.0,
        .query_beam_eta = p.query_beams ? eta_beam : 0.0,
        .photon_beam_eta =
            p.photon_beams ? upbp.photon_beam_eta * p.photon_beam_radius * n_beam : 0.0,
        .short_photon_beams = upbp.short_photon_beams};

    p.ic_light_path_count =
        p.ic_connections ? std::min<uint64_t>(config.ic_connections.light_paths, p.light_path_count)
                         : p.light_path_count;
    p.ic_connection_scale = float(1.0 / double(p.ic_light_path_count));
    p.cache = config.cache;
    p.camera_medium_rule =
        scene.has_media() && !p.query_beams && !p.photon_beams && !p.joint && !p.ic_connections;
    return p;
}

IterationPlan plan_iteration(const ManyLightConfig& config, const Scene& scene,
                             uint64_t iteration) {
    IterationPlan p;
    plan_subpaths(p, config.subpaths, scene);
    p.vpl = config.estimator == ManyLightEstimator::Vpl;
    p.ic = config.estimator == ManyLightEstimator::Ic;
    // No connection or merging technique: the MIS quantities are carried but never weigh.
    p.mis_techniques = MisTechniques{.connections = false};
    if (config.clamp.factor > 0) {
        double d = config.clamp.factor * scene.bounding_sphere().radius;
        if (config.clamp.schedule == VplClampSchedule::Shrinking)
            d *= std::pow(double(iteration), -0.25);
        p.vpl_clamp2 = float(d * d);
    }
    p.vpl_importance = config.importance;
    p.ic_light_path_count = p.light_path_count;
    p.ic_connection_scale = float(1.0 / double(p.ic_light_path_count));
    p.cache = config.cache;
    return p;
}

}  // namespace render::bidirectional
