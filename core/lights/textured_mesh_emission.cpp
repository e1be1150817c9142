#include "core/lights/textured_mesh_emission.h"

#include <algorithm>
#include <cmath>

#include "core/base/memory_budget.h"
#include "core/math/constants.h"
#include "core/sampling/warp.h"
#include "core/shapes/triangle_mesh.h"

namespace render {
namespace {

// Point (b1, b2) of the unit triangle's cell (i, j, d) for a uniform point (s, t) of it.
Vec2 cell_point(int k, int i, int j, int d, Vec2 st) {
    const float inv = 1.0f / float(k);
    if (d == 0) return Vec2((float(i) + st.x) * inv, (float(j) + st.y) * inv);
    return Vec2((float(i + 1) - st.x) * inv, (float(j + 1) - st.y) * inv);
}

}  // namespace

TexturedMeshEmission::TexturedMeshEmission(const TriangleMesh& mesh, const Texture& radiance)
    : mesh_(mesh) {
    const size_t triangles = mesh.triangle_count();
    const std::vector<Vec3>& pos = mesh.positions();
    const std::vector<uint32_t>& idx = mesh.indices();
    k_ = int(std::clamp(std::floor(std::sqrt(double(kMaxCells) / (2.0 * double(triangles)))), 1.0,
                        16.0));
    const size_t slots = 2 * size_t(k_) * size_t(k_);
    // The worker's memory budget (docs/guide/reliability.md, "The memory budget"): the cells'
    // weights, pdf and cdf (16 bytes a slot) and the locator's grid (at most 4 cells a triangle, 4
    // bytes each, and its lists, a few entries a triangle), charged before they are allocated.
    charge_scene_memory(saturating_product(triangles, slots * 16 + 64),
                        "the textured emitter on " + mesh.to_string());

    // Luminance at each cell's centroid, then the defensive floor.
    std::vector<float> weights(triangles * slots, 0.0f);
    cell_area_.assign(triangles, 0.0f);
    double area_sum = 0, weighted = 0;
    for (size_t t = 0; t < triangles; ++t) {
        const float area = 0.5f * length(cross(pos[idx[3 * t + 1]] - pos[idx[3 * t]],
                                               pos[idx[3 * t + 2]] - pos[idx[3 * t]]));
        if (!(area > 0) || !std::isfinite(area)) continue;  // never sampled, as TriangleMesh
        cell_area_[t] = area / float(k_ * k_);
        for (int i = 0; i < k_; ++i)
            for (int j = 0; i + j < k_; ++j)
                for (int d = 0; d < 2 && i + j + d < k_; ++d) {
                    const Vec2 b = cell_point(k_, i, j, d, Vec2(1.0f / 3, 1.0f / 3));
                    const float lum =
                        std::max(0.0f, radiance.eval(mesh.uv_of(t, b.x, b.y)).luminance());
                    weights[t * slots + size_t(2 * (i * k_ + j) + d)] = lum;
                    weighted += double(lum) * cell_area_[t];
                    area_sum += cell_area_[t];
                }
    }
    const float floor_lum = area_sum > 0 ? float(0.1 * weighted / area_sum) : 0.0f;
    for (size_t t = 0; t < triangles; ++t)
        for (int i = 0; i < k_; ++i)
            for (int j = 0; i + j < k_; ++j)
                for (int d = 0; d < 2 && i + j + d < k_; ++d) {
                    float& w = weights[t * slots + size_t(2 * (i * k_ + j) + d)];
                    // All black: by area alone (nothing is emitted; sampling must not fail).
                    w = cell_area_[t] * (floor_lum > 0 ? w + floor_lum : 1.0f);
                }
    cells_ = Distribution1D(std::move(weights));

    // The locator: about one triangle per grid cell, at most 256 cells along an axis; thin
    // axes (a flat light) get one cell. The cell grows until there are at most 4 grid cells
    // per triangle and the lists hold at most 16 entries per triangle (long thin triangles
    // would otherwise be listed in many cells).
    Aabb box = mesh.bounds();
    const Vec3 extent = box.hi - box.lo;
    auto max_abs = [](const Vec3& v) {
        return std::max({std::abs(v.x), std::abs(v.y), std::abs(v.z)});
    };
    const float margin = 1e-4f * length(extent) + 1e-6f * (max_abs(box.lo) + max_abs(box.hi));
    box.lo = box.lo - Vec3(margin);
    box.hi = box.hi + Vec3(margin);
    const Vec3 size = box.hi - box.lo;
    lo_ = box.lo;
    auto range = [&](size_t t, int lo[3], int hi[3]) {
        Aabb b;
        for (int v = 0; v < 3; ++v) b.expand(pos[idx[3 * t + v]]);
        for (int a = 0; a < 3; ++a) {
            auto at = [&](float x) {
                const float c = cell_size_[a] > 0 ? (x - lo_[a]) / cell_size_[a] : 0.0f;
                return std::clamp(int(std::floor(c)), 0, n_[a] - 1);
            };
            lo[a] = at(b.lo[a] - margin);
            hi[a] = at(b.hi[a] + margin);
        }
    };
    const double target = double(std::max<size_t>(triangles, 1));
    double cell = std::cbrt(double(size.x) * size.y * size.z / target);
    for (;;) {
        double cells = 1;
        for (int a = 0; a < 3; ++a) {
            n_[a] = cell > 0 ? int(std::clamp(std::ceil(double(size[a]) / cell), 1.0, 256.0)) : 1;
            cells *= n_[a];
        }
        if (cell > 0 && cells > 4 * target + 8) {
            cell *= 1.26;
            continue;
        }
        cell_size_ = Vec3(size.x / float(n_[0]), size.y / float(n_[1]), size.z / float(n_[2]));
        if (cells <= 1) break;
        double entries = 0;
        for (size_t t = 0; t < triangles; ++t) {
            if (!(cell_area_[t] > 0)) continue;
            int lo[3], hi[3];
            range(t, lo, hi);
            entries += double(hi[0] - lo[0] + 1) * (hi[1] - lo[1] + 1) * (hi[2] - lo[2] + 1);
        }
        if (entries <= 16 * target + 4096) break;
        cell *= 2;
    }
    const size_t grid_cells = size_t(n_[0]) * size_t(n_[1]) * size_t(n_[2]);
    std::vector<uint32_t> counts(grid_cells + 1, 0);
    for (int pass = 0; pass < 2; ++pass) {
        if (pass == 1) {
            grid_start_.assign(grid_cells + 1, 0);
            for (size_t c = 0; c < grid_cells; ++c) grid_start_[c + 1] = grid_start_[c] + counts[c];
            grid_triangles_.resize(grid_start_.back());
            std::fill(counts.begin(), counts.end(), 0);
        }
        for (size_t t = 0; t < triangles; ++t) {
            if (!(cell_area_[t] > 0)) continue;
            int lo[3], hi[3];
            range(t, lo, hi);
            for (int z = lo[2]; z <= hi[2]; ++z)
                for (int y = lo[1]; y <= hi[1]; ++y)
                    for (int x = lo[0]; x <= hi[0]; ++x) {
                        const size_t c =
                            (size_t(z) * size_t(n_[1]) + size_t(y)) * size_t(n_[0]) + size_t(x);
                        if (pass == 1) grid_triangles_[grid_start_[c] + counts[c]] = uint32_t(t);
                        ++counts[c];
                    }
        }
    }
}

size_t TexturedMeshEmission::cell_of(float b1, float b2) const {
    const float x = b1 * float(k_), y = b2 * float(k_);
    int i = std::clamp(int(std::floor(x)), 0, k_ - 1),
        j = std::clamp(int(std::floor(y)), 0, k_ - 1);
    int d = (x - float(i)) + (y - float(j)) > 1 ? 1 : 0;
    // Rounding at the triangle's far edge: the nearest cell that exists.
    while (i + j + d > k_ - 1) {
        if (d == 1)
            d = 0;
        else if (i >= j)
            --i;
        else
            --j;
    }
    return size_t(2 * (i * k_ + j) + d);
}

float TexturedMeshEmission::pdf_of(size_t tri, size_t cell) const {
    const size_t slots = 2 * size_t(k_) * size_t(k_);
    return cells_.discrete_probability(tri * slots + cell) / cell_area_[tri];
}

ShapeSample TexturedMeshEmission::sample(Vec2 u) const {
    ShapeSample s;
    if (cells_.size() == 0) return s;
    float u_remapped;
    const size_t index = cells_.sample_discrete(u.x, nullptr, &u_remapped);
    const size_t slots = 2 * size_t(k_) * size_t(k_);
    const size_t tri = index / slots, cell = index % slots;
    if (!(cell_area_[tri] > 0)) return s;
    const int d = int(cell % 2), i = int(cell / 2) / k_, j = int(cell / 2) % k_;
    const Vec2 b = cell_point(k_, i, j, d, warp::square_to_uniform_triangle(Vec2(u_remapped, u.y)));
    const std::vector<Vec3>& pos = mesh_.positions();
    const std::vector<uint32_t>& idx = mesh_.indices();
    s.p = pos[idx[3 * tri]] * (1.0f - b.x - b.y) + pos[idx[3 * tri + 1]] * b.x +
          pos[idx[3 * tri + 2]] * b.y;
    s.n = mesh_.face_normal(tri);
    s.uv = mesh_.uv_of(tri, b.x, b.y);
    // From the point's own cell, as find() will see it (they differ only by rounding at cell
    // edges, where either density is right).
    s.pdf_area = pdf_of(tri, cell_of(b.x, b.y));
    return s;
}

bool TexturedMeshEmission::barycentrics(size_t tri, const Vec3& p, float& b1, float& b2,
                                        float& distance) const {
    const std::vector<Vec3>& pos = mesh_.positions();
    const std::vector<uint32_t>& idx = mesh_.indices();
    const Vec3& p0 = pos[idx[3 * tri]];
    const Vec3 e1 = pos[idx[3 * tri + 1]] - p0, e2 = pos[idx[3 * tri + 2]] - p0;
    const Vec3 n = cross(e1, e2);
    const float n2 = length_squared(n);
    if (!(n2 > 0)) return false;
    const Vec3 d = p - p0;
    b1 = dot(cross(d, e2), n) / n2;
    b2 = dot(cross(e1, d), n) / n2;
    const float margin = 1e-4f;
    if (b1 < -margin || b2 < -margin || b1 + b2 > 1 + margin) return false;
    b1 = std::clamp(b1, 0.0f, 1.0f);
    b2 = std::clamp(b2, 0.0f, 1.0f - b1);
    distance = std::abs(dot(d, n)) / std::sqrt(n2);
    return true;
}

bool TexturedMeshEmission::find(const Vec3& p, Vec2& uv, float& pdf_area,
                                size_t* cell_index) const {
    unsigned tri;
    Vec2 b;
    if (!locate(p, tri, b)) return false;
    uv = mesh_.uv_of(tri, b.x, b.y);
    const size_t in_triangle = cell_of(b.x, b.y);
    pdf_area = pdf_of(tri, in_triangle);
    if (cell_index) *cell_index = size_t(tri) * 2 * size_t(k_) * size_t(k_) + in_triangle;
    return true;
}

bool TexturedMeshEmission::locate(const Vec3& p, unsigned& tri_found, Vec2& b) const {
    int c[3];
    for (int a = 0; a < 3; ++a) {
        const float x = cell_size_[a] > 0 ? (p[a] - lo_[a]) / cell_size_[a] : 0.0f;
        if (!(x >= -1e-3f * float(n_[a]) && x <= float(n_[a]) * (1 + 1e-3f))) return false;
        c[a] = std::clamp(int(std::floor(x)), 0, n_[a] - 1);
    }
    const size_t cell =
        (size_t(c[2]) * size_t(n_[1]) + size_t(c[1])) * size_t(n_[0]) + size_t(c[0]);
    float best = kInfinity, best_b1 = 0, best_b2 = 0;
    size_t best_tri = 0;
    for (uint32_t k = grid_start_[cell]; k < grid_start_[cell + 1]; ++k) {
        const size_t tri = grid_triangles_[k];
        float b1, b2, distance;
        if (!barycentrics(tri, p, b1, b2, distance) || !(distance < best)) continue;
        best = distance;
        best_tri = tri;
        best_b1 = b1;
        best_b2 = b2;
    }
    if (best == kInfinity) return false;
    tri_found = unsigned(best_tri);
    b = Vec2(best_b1, best_b2);
    return true;
}

}  // namespace render
