#include "core/integrators/beam_grid.h"

#include <algorithm>
#include <cmath>
#include <utility>

namespace render {

namespace {

// The parameter range of `ray` (unit direction or not) inside the box; false if it misses.
bool clip(const Vec3& o, const Vec3& d, const Vec3& lo, const Vec3& hi, float& t0, float& t1) {
    for (int a = 0; a < 3; ++a) {
        if (d[a] == 0.0f) {
            if (o[a] < lo[a] || o[a] > hi[a]) return false;
            continue;
        }
        float n = (lo[a] - o[a]) / d[a], f = (hi[a] - o[a]) / d[a];
        if (n > f) std::swap(n, f);
        t0 = std::max(t0, n);
        t1 = std::min(t1, f);
    }
    return t0 <= t1;
}

}  // namespace

void UniformBeamGrid::build(const std::vector<BeamLine>& beams, float radius, const Aabb& bounds,
                            double cells_per_beam) {
    beams_ = &beams;
    radius_ = radius;
    cell_start_.clear();
    beam_ids_.clear();
    // The beams' box, clipped to the query bounds grown by r.
    const Vec3 grow(radius);
    Aabb box;
    for (const BeamLine& b : beams) {
        float t0 = 0, t1 = b.length;
        if (!clip(b.origin, b.direction, bounds.lo - grow, bounds.hi + grow, t0, t1)) continue;
        box.expand(b.origin + b.direction * t0);
        box.expand(b.origin + b.direction * t1);
    }
    if (box.empty()) {
        res_[0] = res_[1] = res_[2] = 0;
        return;
    }
    lo_ = box.lo - grow;
    hi_ = box.hi + grow;
    const Vec3 extent = hi_ - lo_;
    const double volume = double(extent.x) * extent.y * extent.z;
    const double cells = std::max(1.0, cells_per_beam * double(beams.size()));
    const double side = std::cbrt(volume / cells);
    for (int a = 0; a < 3; ++a) {
        res_[a] = std::clamp(int(std::ceil(extent[a] / std::max(side, 1e-30))), 1, 256);
        cell_size_[a] = extent[a] / float(res_[a]);
    }
    const size_t cell_count = size_t(res_[0]) * res_[1] * res_[2];
    // Two passes over the beams (count, then fill: 4 bytes per reference, no pair list to
    // sort), each beam walked in steps of one cell's smallest side, each step's box grown by r;
    // a per-cell stamp drops repeats of the same beam within a pass.
    const float step = std::min({cell_size_.x, cell_size_.y, cell_size_.z});
    auto cell_of = [&](float v, int a) {
        return std::clamp(int((v - lo_[a]) / cell_size_[a]), 0, res_[a] - 1);
    };
    std::vector<uint32_t> stamp;
    auto for_each_cell = [&](auto&& add) {
        stamp.assign(cell_count, UINT32_MAX);
        for (uint32_t i = 0; i < beams.size(); ++i) {
            const BeamLine& b = beams[i];
            float t0 = 0, t1 = b.length;
            if (!clip(b.origin, b.direction, lo_, hi_, t0, t1)) continue;
            for (float s = t0; s <= t1; s += step) {
                const float e = std::min(s + step, t1);
                const Vec3 p = b.origin + b.direction * s, q = b.origin + b.direction * e;
                int c0[3], c1[3];
                for (int a = 0; a < 3; ++a) {
                    c0[a] = cell_of(std::min(p[a], q[a]) - radius, a);
                    c1[a] = cell_of(std::max(p[a], q[a]) + radius, a);
                }
                for (int z = c0[2]; z <= c1[2]; ++z)
                    for (int y = c0[1]; y <= c1[1]; ++y)
                        for (int x = c0[0]; x <= c1[0]; ++x) {
                            const uint32_t c = uint32_t((size_t(z) * res_[1] + y) * res_[0] + x);
                            if (stamp[c] == i) continue;
                            stamp[c] = i;
                            add(c, i);
                        }
                if (e >= t1) break;
            }
        }
    };
    // Compressed rows, beams in index order within a cell.
    cell_start_.assign(cell_count + 1, 0);
    for_each_cell([&](uint32_t c, uint32_t) { ++cell_start_[c + 1]; });
    for (size_t c = 0; c < cell_count; ++c) cell_start_[c + 1] += cell_start_[c];
    beam_ids_.resize(cell_start_[cell_count]);
    std::vector<uint32_t> fill(cell_start_.begin(), cell_start_.end() - 1);
    for_each_cell([&](uint32_t c, uint32_t i) { beam_ids_[fill[c]++] = i; });
}

void UniformBeamGrid::query(const Ray& ray, BeamsAlongRay::VisitFunction visit, void* user) const {
    if (!beams_ || beam_ids_.empty()) return;
    float t0 = ray.t_min, t1 = ray.t_max;
    if (!clip(ray.origin, ray.direction, lo_, hi_, t0, t1)) return;
    // 3-D DDA (Amanatides and Woo) from the entry point.
    int cell[3], step[3];
    float t_next[3], t_delta[3];
    const Vec3 entry = ray.at(t0);
    for (int a = 0; a < 3; ++a) {
        cell[a] = std::clamp(int((entry[a] - lo_[a]) / cell_size_[a]), 0, res_[a] - 1);
        const float d = ray.direction[a];
        if (d > 0) {
            step[a] = 1;
            t_next[a] = (lo_[a] + float(cell[a] + 1) * cell_size_[a] - ray.origin[a]) / d;
            t_delta[a] = cell_size_[a] / d;
        } else if (d < 0) {
            step[a] = -1;
            t_next[a] = (lo_[a] + float(cell[a]) * cell_size_[a] - ray.origin[a]) / d;
            t_delta[a] = -cell_size_[a] / d;
        } else {
            step[a] = 0;
            t_next[a] = kInfinity;
            t_delta[a] = kInfinity;
        }
    }
    const float radius2_margin = 1.001f * radius_ * radius_;
    float t_enter = t0;
    for (;;) {
        const int a = t_next[0] < t_next[1] ? (t_next[0] < t_next[2] ? 0 : 2)
                                            : (t_next[1] < t_next[2] ? 1 : 2);
        const float t_exit = std::min(t_next[a], t1);
        const bool last = t_next[a] >= t1;
        const size_t c = (size_t(cell[2]) * res_[1] + cell[1]) * res_[0] + cell[0];
        for (uint32_t k = cell_start_[c]; k < cell_start_[c + 1]; ++k) {
            const uint32_t i = beam_ids_[k];
            const BeamLine& beam = (*beams_)[i];
            // Most of a cell's beams pass farther than r from the query's line: rejected
            // without the square root and divisions of closest_approach, by the squared
            // distance (dot(w, n)^2 / sin^2) with a margin far above float rounding, so that
            // only beams the exact test below rejects are skipped (images bit-identical).
            const Vec3 n = cross(ray.direction, beam.direction);
            const float wn = dot(ray.origin - beam.origin, n);
            if (wn * wn > radius2_margin * length_squared(n)) continue;
            BeamApproach ap;
            if (!closest_approach(ray, beam, ap)) continue;
            // This cell's stretch of the query owns the approach: each beam reported once.
            if (!(ap.t_ray >= t_enter && (ap.t_ray < t_exit || (last && ap.t_ray <= t_exit))))
                continue;
            if (!(ap.t_ray >= ray.t_min && ap.t_ray <= ray.t_max)) continue;
            if (!(ap.t_beam >= 0 && ap.t_beam <= beam.length)) continue;
            if (!(ap.distance <= radius_)) continue;
            visit(user, i, ap);
        }
        if (last) return;
        cell[a] += step[a];
        if (cell[a] < 0 || cell[a] >= res_[a]) return;
        t_enter = t_next[a];
        t_next[a] += t_delta[a];
    }
}

}  // namespace render
