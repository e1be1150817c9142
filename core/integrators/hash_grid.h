#pragma once

// Fixed-radius range queries over points (photon/light vertices), as the VCM report's
// section 5 suggests: a hashed uniform grid with cell size 2r, so a query sphere of radius r
// overlaps at most 2 x 2 x 2 cells. Built once per iteration (in parallel), then read-only and
// shared by all threads. A cell's points are visited in increasing index order whatever the
// number of threads that built the grid, so sums over the visits do not depend on it.

#include <array>
#include <cmath>
#include <cstdint>
#include <span>
#include <vector>

#include "core/math/vec.h"
#include "core/util/function_ref.h"

namespace render {

class HashGrid {
  public:
    // Indexes `positions` (copied: the caller may change them after). Point i is visited as
    // ids[i], or as i when `ids` is empty (ids.size() must otherwise equal positions.size()):
    // a caller whose points stand for records elsewhere passes their indices here, so that a
    // query goes from a point straight to its record without a lookup of its own. Runs in the
    // calling TBB arena; the buffers are kept for the next build.
    void build(const std::vector<Vec3>& positions, double radius,
               std::span<const uint32_t> ids = {});
    // The same over n points whose positions position(i) gives (read three times, never
    // kept beyond the grid's own copies): a caller whose records hold the positions does not
    // need an array of them beside the grid.
    void build(size_t n, FunctionRef<Vec3(size_t)> position, double radius,
               std::span<const uint32_t> ids = {});

    // Calls visit(id) for every point with |positions[i] - p| <= radius, in increasing i
    // within each of the (at most 8) cells visited, the cells in a fixed order.
    template <typename Visit>
    void for_each_within_radius(const Vec3& p, Visit&& visit) const {
        if (entries_.empty()) return;
        double c[3], f[3], reach2[3];
        for (int a = 0; a < 3; ++a) {
            double x = (double(p[a]) - lo_[a]) * inv_cell_size_;
            c[a] = std::floor(x);
            f[a] = x - c[a];
            // The squared distance, in cells, from p to the neighbour cell on the side the
            // sphere reaches over (a cell is 2r wide: the sphere reaches over one side only).
            const double d = f[a] < 0.5 ? f[a] : 1.0 - f[a];
            reach2[a] = d * d;
        }
        // The 8 cells around p; two of them may hash to one bucket, which is visited once, at
        // its first cell's place. A cell the sphere cannot reach (its nearest corner or edge
        // farther than r) is skipped unless another, reached, cell shares its bucket: that
        // skips ~14 % of the buckets (a corner cell is reached with probability pi/6, an edge
        // cell pi/4) without changing which points are visited, nor their order.
        std::array<uint32_t, 8> buckets;
        std::array<bool, 8> reached;
        int count = 0;
        for (int corner = 0; corner < 8; ++corner) {
            int64_t cell[3];
            double distance2 = 0;
            for (int a = 0; a < 3; ++a) {
                const bool stepped = (corner >> a) & 1;
                cell[a] = int64_t(c[a]) + (stepped ? (f[a] < 0.5 ? -1 : 1) : 0);
                if (stepped) distance2 += reach2[a];
            }
            const bool reaches = distance2 <= kReach2;
            const uint32_t bucket = hash(cell[0], cell[1], cell[2]);
            int k = 0;
            while (k < count && buckets[k] != bucket) ++k;
            if (k == count) {
                buckets[count] = bucket;
                reached[count++] = reaches;
            } else {
                reached[k] = reached[k] || reaches;
            }
        }
        // The buckets' bounds, then their first entries, are requested for all cells before
        // any is read: the cells' cache misses overlap instead of following one another.
        for (int k = 0; k < count; ++k)
            if (reached[k]) __builtin_prefetch(&cell_starts_[buckets[k]]);
        std::array<uint32_t, 8> begin, end;
        for (int k = 0; k < count; ++k) {
            begin[k] = reached[k] ? cell_starts_[buckets[k]] : 0;
            end[k] = reached[k] ? cell_starts_[buckets[k] + 1] : 0;
            if (begin[k] < end[k]) __builtin_prefetch(&entries_[begin[k]]);
        }
        for (int k = 0; k < count; ++k)
            for (uint32_t j = begin[k]; j < end[k]; ++j) {
                const Entry& e = entries_[j];
                if (length_squared(e.p - p) <= radius2_) visit(e.index);
            }
    }

    // for_each_within_radius in two steps: first prefetch(id) for every point found, then
    // visit(id) for each, in the same order. The caller's records of the points are then
    // requested from memory together, instead of one miss after the other inside a visit too
    // long for the processor to run ahead of it.
    template <typename Prefetch, typename Visit>
    void for_each_within_radius(const Vec3& p, Prefetch&& prefetch, Visit&& visit) const {
        std::array<uint32_t, 32> found;
        size_t count = 0;
        for_each_within_radius(p, [&](uint32_t id) {
            if (count == found.size()) {
                for (uint32_t f : found) visit(f);
                count = 0;
            }
            prefetch(id);
            found[count++] = id;
        });
        for (size_t k = 0; k < count; ++k) visit(found[k]);
    }

  private:
    // A point within the radius (float distance, float squared radius) lies within
    // r (1 + ~1e-6) of p, i.e. within 0.25 (1 + ~1e-6) squared cells: a margin of 1e-3 keeps
    // every cell that could hold one, whatever the rounding of the cell coordinates.
    static constexpr double kReach2 = 0.25 * (1.0 + 1e-3);

    uint32_t hash(int64_t x, int64_t y, int64_t z) const {
        // Teschner et al. 2003 spatial hash.
        uint64_t h =
            (uint64_t(x) * 73856093u) ^ (uint64_t(y) * 19349663u) ^ (uint64_t(z) * 83492791u);
        return uint32_t(h % table_size_);
    }
    int64_t cell_coordinate(double value, int axis) const {
        return int64_t(std::floor((value - lo_[axis]) * inv_cell_size_));
    }

    double lo_[3] = {0, 0, 0};
    double inv_cell_size_ = 1;
    float radius2_ = 0;
    uint64_t table_size_ = 1;
    std::vector<uint32_t> cell_starts_;  // table_size_ + 1 prefix sums
    // The points sorted by bucket, then by index, each with a copy of its position and its id: a
    // bucket's candidates are one sequential read, and a query touches nothing else of a point (the
    // caller's records only for the points within the radius). Queries were bound by the
    // cache misses of an index, then a position far from its neighbours'
    // (docs/results/performance.md).
    struct Entry {
        Vec3 p;
        uint32_t index;  // the point's id (build's ids[i], or i)
    };
    std::vector<Entry> entries_;
    // Scratch of the build (hash_grid.cpp): per block and group of buckets, a count and then
    // a slot; the groups' starts.
    std::vector<uint32_t> slots_, group_starts_;
};

}  // namespace render
