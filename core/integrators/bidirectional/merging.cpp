// Merging: the light vertices within the radius of an eye vertex, each MIS-weighted (eqs. 38
// and 39) or, in ppm, unweighted.
#include "core/integrators/bidirectional/iteration.h"

namespace render::bidirectional {

float Iteration::merge_joint_ratio(const LightVertex& lv, const Vertex& v) const {
    if (!plan_.joint || !(v.joint_distance_pdf > 0) ||
        !joint_light_side(lv.path_length, lv.finite_light))
        return 0.0f;
    return joint_pdf_l(v.previous, v.p, lv.previous()) / v.joint_distance_pdf;
}

Rgb Iteration::merge(const Vertex& v, const Vec3& wo, const SubpathState& state) const {
    const bool medium = v.in_medium();
    const HashGrid& grid = medium ? medium_grid_ : surface_grid_;
    Rgb sum(0.0f);
    // What a merge reads of a light vertex is its first cache line (LightVertex), and its second
    // where J1 (previous) or photon beams (photon_beam) take part in the weight.
    const bool last_line = (plan_.joint && v.joint_distance_pdf > 0) || v.photon_beam > 0;
    auto prefetch = [&](uint32_t i) {
        const LightVertex& lv = light_vertices_[i];
        __builtin_prefetch(&lv);
        if (last_line) __builtin_prefetch(reinterpret_cast<const char*>(&lv) + 64);
    };
    grid.for_each_within_radius(v.p, prefetch, [&](uint32_t i) {
        const LightVertex& lv = light_vertices_[i];
        if (lv.path_length + state.path_length > plan_.max_length) return;
        // The light subpath's last region goes on through the eye vertex unless its surface
        // declares media: both must be in the same medium there (docs/design/media.md).
        if (plan_.camera_medium_rule && v.keeps_medium() &&
            light_vertex_media_[i].arrival != v.medium)
            return;
        // The photon arrived from lv.wo; the eye vertex scatters it toward wo.
        const auto [f, pdf_w] = v.evaluate(wo, lv.wo);
        if (f.is_black()) return;
        float weight = 1.0f;
        if (!plan_.ppm) {
            // Eqs. (38) and (39).
            weight = mis_.weight_merge(
                lv.mis, state.mis,
                {.eye_forward_w = pdf_w.forward,
                 .eye_reverse_w = pdf_w.reverse,
                 .medium = medium,
                 .query_beam = v.query_beam,
                 .photon_beam = v.photon_beam > 0 && lv.photon_beam() > 0
                                    ? mis_.photon_beam_merge_term(length(cross(wo, lv.wo)),
                                                                  lv.arrival_distance(),
                                                                  v.arrival_distance, v.sigma_t)
                                    : 0.0f,
                 .light_joint_ratio = merge_joint_ratio(lv, v)});
        }
        Rgb photon = lv.throughput;
        if (medium) {
            // Both subpaths' throughputs carry sigma_s at their medium vertex (the distance
            // sampling weight); the merged path scatters once, so one of them is divided out.
            const Rgb sigma_s = lv.medium()->sigma_s(lv.p);
            for (int c = 0; c < 3; ++c) photon[c] = sigma_s[c] > 0 ? photon[c] / sigma_s[c] : 0.0f;
        }
        sum += f * photon * weight;
    });
    return sum * (medium ? plan_.vm_normalization_volume : plan_.vm_normalization);
}

}  // namespace render::bidirectional
