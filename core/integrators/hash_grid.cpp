#include "core/integrators/hash_grid.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <array>
#include <limits>
#include <stdexcept>
#include <string>

namespace render {
namespace {

using Range = tbb::blocked_range<size_t>;
// Points per block of the first two passes: fixed, so that the order of the points within a
// group does not depend on the thread count.
constexpr size_t kBlockPoints = 16384;
// Buckets per group: a group's slice of cell_starts_ (16 KiB) stays in the L1 cache while its
// points are counted and placed.
constexpr size_t kGroupBuckets = 4096;

}  // namespace

// A counting sort of the points by bucket in two levels, without atomics: the points are first
// distributed, block by block, into groups of consecutive buckets (each block counts its
// points per group, an exclusive prefix over (group, block) gives every block its slots), then
// each group is counting-sorted by bucket on its own. Both levels are stable, so a bucket's
// points are in increasing index order, as a serial counting sort leaves them, whatever the
// number of threads.
void HashGrid::build(const std::vector<Vec3>& positions, double radius,
                     std::span<const uint32_t> ids) {
    build(
        positions.size(), [&](size_t i) { return positions[i]; }, radius, ids);
}

void HashGrid::build(size_t n, FunctionRef<Vec3(size_t)> position, double radius,
                     std::span<const uint32_t> ids) {
    if (!ids.empty() && ids.size() != n)
        throw std::invalid_argument("HashGrid::build: " + std::to_string(ids.size()) + " ids for " +
                                    std::to_string(n) + " points");
    radius2_ = float(radius * radius);
    inv_cell_size_ = 1.0 / (2.0 * radius);
    using Corner = std::array<double, 3>;
    constexpr double inf = std::numeric_limits<double>::infinity();
    // The minimum is exact whatever the order of the comparisons.
    const Corner lo = tbb::parallel_reduce(
        Range(0, n, kBlockPoints), Corner{inf, inf, inf},
        [&](const Range& r, Corner m) {
            for (size_t i = r.begin(); i < r.end(); ++i) {
                const Vec3 p = position(i);
                for (int a = 0; a < 3; ++a) m[a] = std::min(m[a], double(p[a]));
            }
            return m;
        },
        [](Corner a, const Corner& b) {
            for (int k = 0; k < 3; ++k) a[k] = std::min(a[k], b[k]);
            return a;
        });
    for (int a = 0; a < 3; ++a) lo_[a] = lo[a];
    table_size_ = std::max<uint64_t>(n, 1);
    cell_starts_.resize(table_size_ + 1);
    // Grow with headroom and without copying: a vector that reallocates inside resize() holds
    // the old entries and the new ones at once, at the iteration's peak of memory.
    if (entries_.capacity() < n) {
        entries_ = std::vector<Entry>();
        entries_.reserve(n + n / 8);
    }
    entries_.resize(n);

    auto bucket_at = [&](const Vec3& p) {
        return hash(cell_coordinate(p.x, 0), cell_coordinate(p.y, 1), cell_coordinate(p.z, 2));
    };
    auto bucket_of = [&](size_t i) { return bucket_at(position(i)); };
    const size_t groups = (table_size_ + kGroupBuckets - 1) / kGroupBuckets;
    const size_t blocks = (n + kBlockPoints - 1) / kBlockPoints;
    // slots_[block * groups + group]: the block's count in the group, then its first slot.
    slots_.assign(blocks * groups, 0);
    tbb::parallel_for(size_t(0), blocks, [&](size_t b) {
        uint32_t* count = slots_.data() + b * groups;
        for (size_t i = b * kBlockPoints; i < std::min(n, (b + 1) * kBlockPoints); ++i)
            ++count[bucket_of(i) / kGroupBuckets];
    });
    group_starts_.resize(groups + 1);
    uint32_t slot = 0;
    for (size_t g = 0; g < groups; ++g) {
        group_starts_[g] = slot;
        for (size_t b = 0; b < blocks; ++b) {
            const uint32_t count = slots_[b * groups + g];
            slots_[b * groups + g] = slot;
            slot += count;
        }
    }
    group_starts_[groups] = slot;
    // The points (position, id) in group order; within a group in block order, then point
    // order.
    tbb::parallel_for(size_t(0), blocks, [&](size_t b) {
        uint32_t* next = slots_.data() + b * groups;
        for (size_t i = b * kBlockPoints; i < std::min(n, (b + 1) * kBlockPoints); ++i) {
            const Vec3 p = position(i);
            entries_[next[bucket_at(p) / kGroupBuckets]++] = {p,
                                                              ids.empty() ? uint32_t(i) : ids[i]};
        }
    });
    // Each group sorted by bucket in place, through a copy of its entries (the bucket is
    // recomputed from the same position, so it is the one counted above).
    tbb::parallel_for(size_t(0), groups, [&](size_t g) {
        const size_t first = g * kGroupBuckets, end = std::min(table_size_, first + kGroupBuckets);
        const std::vector<Entry> group(entries_.begin() + group_starts_[g],
                                       entries_.begin() + group_starts_[g + 1]);
        std::fill(cell_starts_.begin() + first, cell_starts_.begin() + end, 0);
        for (const Entry& e : group) ++cell_starts_[bucket_at(e.p)];
        uint32_t start = group_starts_[g];
        for (size_t bucket = first; bucket < end; ++bucket) {
            const uint32_t count = cell_starts_[bucket];
            cell_starts_[bucket] = start;
            start += count;
        }
        for (const Entry& e : group) entries_[cell_starts_[bucket_at(e.p)]++] = e;
        // cell_starts_[bucket] is now the next bucket's start: shift back by one bucket.
        for (size_t bucket = end; bucket-- > first + 1;)
            cell_starts_[bucket] = cell_starts_[bucket - 1];
        cell_starts_[first] = group_starts_[g];
    });
    cell_starts_[table_size_] = uint32_t(n);
}

}  // namespace render
