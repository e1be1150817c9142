#include "core/integrators/medium_segment.h"

#include <cmath>

#include "core/media/medium.h"
#include "core/media/medium_interface.h"
#include "core/scene/scene.h"

namespace render {
void SegmentDensityBuilder::add_piece(const Medium* medium, const Ray& ray, float length) {
    // Sampling the start from the far end (first piece, starting at a medium vertex): in a
    // heterogeneous medium that density has sigma_t at the start, not at the end.
    const bool at_start = pieces_ == 0 && start_in_medium_;
    const Medium::PieceDensities d =
        medium ? medium->piece_densities(ray, length, at_start) : Medium::PieceDensities{};
    const float pass = d.pass, scatter = d.scatter_at_end;
    if (pieces_ == 0) {
        first_start_factor_ = start_in_medium_ ? d.scatter_at_start : pass;
    } else {
        pass_before_last_ *= last_pass_;
        pass_after_first_ *= pass;
    }
    last_pass_ = pass;
    last_scatter_ = scatter;
    homogeneous_ = homogeneous_ && (!medium || medium->is_homogeneous());
    chromatic_grid_ =
        chromatic_grid_ || (medium && !medium->is_homogeneous() && !medium->pass_weight_is_one());
    ++pieces_;
}

SegmentDensities SegmentDensityBuilder::finish(bool end_in_medium) const {
    if (pieces_ == 0) return {};
    SegmentDensities d;
    d.toward_end = pass_before_last_ * (end_in_medium ? last_scatter_ : last_pass_);
    d.toward_start = pass_after_first_ * first_start_factor_;
    d.homogeneous = homogeneous_;
    d.short_beam_support = short_beam_support();
    return d;
}

SampledSegment sample_segment(const Scene& scene, Ray ray, const Medium* medium,
                              bool start_in_medium, Rng& rng, RenderStats& stats,
                              const TracedPieces* traced) {
    SampledSegment out;
    SegmentDensityBuilder densities(start_in_medium);
    const Vec3 start = ray.origin;
    for (int crossing = 0; crossing <= kMaxNullCrossings; ++crossing) {
        SurfaceInteraction si;
        bool hit;
        if (traced && crossing < traced->count) {
            hit = traced->hit[crossing];
            if (hit) si = traced->si[crossing];
        } else {
            ++stats.rays;
            hit = scene.intersect(ray, si);
        }
        const float t_end = hit ? si.t : kInfinity;
        if (medium) {
            if (crossing == 0 && !medium->is_homogeneous() && !medium->pass_weight_is_one()) {
                out.first_piece_rng = rng;
                out.first_piece_t_max = t_end;
            }
            const MediumSample ms = medium->sample(ray, t_end, rng);
            if (ms.scattered) out.source_weight = out.weight * ms.source_weight;
            out.weight *= ms.weight;
            if (ms.scattered) {
                densities.add_piece(medium, ray, ms.t);
                out.end = SegmentEnd::Medium;
                out.position = ray.at(ms.t);
                out.medium = medium;
                out.densities = densities.finish(true);
                out.one_piece = densities.pieces() == 1;
                out.distance = length(out.position - start);
                return out;
            }
            if (out.weight.is_black()) break;
        }
        if (!hit) {
            // Leaving the scene; a medium without boundary makes it unreachable in practice.
            if (medium) densities.add_piece(medium, ray, kInfinity);
            out.end = SegmentEnd::Escaped;
            out.medium = medium;
            out.densities = densities.finish(false);
            return out;
        }
        densities.add_piece(medium, ray, si.t);
        if (!si.bsdf->is_null()) {
            out.end = SegmentEnd::Surface;
            out.si = si;
            out.position = si.p;
            out.medium = medium;
            out.densities = densities.finish(false);
            out.one_piece = densities.pieces() == 1;
            out.distance = length(si.p - start);
            return out;
        }
        if (arrives_against_declaration(*si.shape, si.geometric_normal, ray.direction, medium))
            out.against_declaration = true;
        medium = medium_after_surface(si, ray.direction, medium);
        ray = scene.spawn_ray(si.p, si.geometric_normal, ray.direction);
    }
    out.weight = Rgb(0.0f);
    out.end = SegmentEnd::Escaped;
    return out;
}

SegmentConnection connect_segment(const Scene& scene, const Ray& connection, const Medium* medium,
                                  bool start_in_medium, bool end_in_medium, Rng& rng,
                                  RenderStats& stats) {
    SegmentConnection out;
    SegmentDensityBuilder densities(start_in_medium);
    Rgb tr(1.0f);
    Ray ray = connection;
    const bool to_infinity = std::isinf(ray.t_max);
    const Vec3 end = to_infinity ? Vec3() : ray.at(ray.t_max);
    for (int crossing = 0; crossing <= kMaxNullCrossings; ++crossing) {
        SurfaceInteraction si;
        ++stats.rays;
        if (!scene.intersect(ray, si)) {
            if (medium) tr *= medium->transmittance(ray, ray.t_max, rng);
            densities.add_piece(medium, ray, ray.t_max);
            out.end_medium = medium;
            out.transmittance = tr;
            out.densities = densities.finish(end_in_medium);
            out.one_piece = densities.pieces() == 1;
            return out;
        }
        if (!si.bsdf->is_null()) return out;  // blocked
        if (medium) tr *= medium->transmittance(ray, si.t, rng);
        densities.add_piece(medium, ray, si.t);
        if (tr.is_black()) return out;
        if (arrives_against_declaration(*si.shape, si.geometric_normal, ray.direction, medium))
            out.against_declaration = true;
        medium = medium_after_surface(si, ray.direction, medium);
        const Ray next = scene.spawn_ray(si.p, si.geometric_normal, ray.direction);
        const float remaining = to_infinity ? kInfinity : dot(end - next.origin, ray.direction);
        if (!(remaining > 0)) {
            out.end_medium = medium;
            out.transmittance = tr;
            out.densities = densities.finish(end_in_medium);
            out.one_piece = densities.pieces() == 1;
            return out;
        }
        ray = Ray(next.origin, ray.direction, 0.0f, remaining);
    }
    return out;
}

}  // namespace render
