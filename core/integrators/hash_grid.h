#pragma once

// Fixed-radius range queries over points (photon/light vertices), as the VCM report's
// section 5 suggests: a hashed uniform grid with cell size 2r, so a query sphere of radius r
// overlaps at most 2 x 2 x 2 cells. Built once per iteration (in parallel), then read-only and
// shared by all threads. A cell's points are visited in increasing index order whatever the
// number of threads that built the grid, so sums over the visits do not depend on it.

#include <array>
#include <cmath>
#include <cstdint>
#include <vector>

#include "core/math/vec.h"

namespace render {

class HashGrid {
  public:
    // Indexes `positions` (copied: the caller may change them after). Runs in the
    // calling TBB arena; the buffers are kept for the next build.
    void build(const std::vector<Vec3>& positions, double radius);

    // Calls visit(i) for every point i with |positions[i] - p| <= radius.
    template <typename Visit>
    void for_each_within_radius(const Vec3& p, Visit&& visit) const {
        if (entries_.empty()) return;
        double c[3], f[3];
        for (int a = 0; a < 3; ++a) {
            double x = (double(p[a]) - lo_[a]) * inv_cell_size_;
            c[a] = std::floor(x);
            f[a] = x - c[a];
        }
        // The 8 cells around p; two of them may hash to one bucket, which is visited once.
        std::array<uint32_t, 8> buckets;
        int count = 0;
        for (int corner = 0; corner < 8; ++corner) {
            int64_t cell[3];
            for (int a = 0; a < 3; ++a) {
                int64_t step = (corner >> a) & 1 ? (f[a] < 0.5 ? -1 : 1) : 0;
                cell[a] = int64_t(c[a]) + step;
            }
            uint32_t bucket = hash(cell[0], cell[1], cell[2]);
            bool seen = false;
            for (int k = 0; k < count; ++k) seen |= buckets[k] == bucket;
            if (!seen) buckets[count++] = bucket;
        }
        for (int k = 0; k < count; ++k)
            for (uint32_t j = cell_starts_[buckets[k]]; j < cell_starts_[buckets[k] + 1]; ++j) {
                const Entry& e = entries_[j];
                if (length_squared(e.p - p) <= radius2_) visit(e.index);
            }
    }

  private:
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
    // The points sorted by bucket, then by index, each with a copy of its position: a bucket's
    // candidates are one sequential read, and a query touches nothing else of a point (the
    // caller's records only for the points within the radius). Queries were bound by the
    // cache misses of an index, then a position far from its neighbours' (docs/performance.md).
    struct Entry {
        Vec3 p;
        uint32_t index;
    };
    std::vector<Entry> entries_;
    // Scratch of the build (hash_grid.cpp): per block and group of buckets, a count and then
    // a slot; the groups' starts.
    std::vector<uint32_t> slots_, group_starts_;
};

}  // namespace render
