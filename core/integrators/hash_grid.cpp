#include "core/integrators/hash_grid.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>
#include <tbb/parallel_scan.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <limits>

namespace render {
namespace {

using Range = tbb::blocked_range<size_t>;
// Points (or buckets) per task: large enough that a task outweighs its scheduling.
constexpr size_t kGrain = 16384;

}  // namespace

// A counting sort of the points by bucket, in parallel: the buckets' sizes are counted with
// atomic increments, turned into starts by a prefix sum, and the points scattered with atomic
// slot claims; claims interleave differently from run to run, so each bucket's indices are
// then sorted, which gives exactly the serial counting sort's order (increasing index).
void HashGrid::build(const std::vector<Vec3>& positions, double radius) {
    positions_ = &positions;
    radius2_ = float(radius * radius);
    inv_cell_size_ = 1.0 / (2.0 * radius);
    const size_t n = positions.size();
    using Corner = std::array<double, 3>;
    constexpr double inf = std::numeric_limits<double>::infinity();
    // The minimum is exact whatever the order of the comparisons.
    const Corner lo = tbb::parallel_reduce(
        Range(0, n, kGrain), Corner{inf, inf, inf},
        [&](const Range& r, Corner m) {
            for (size_t i = r.begin(); i < r.end(); ++i)
                for (int a = 0; a < 3; ++a) m[a] = std::min(m[a], double(positions[i][a]));
            return m;
        },
        [](Corner a, const Corner& b) {
            for (int k = 0; k < 3; ++k) a[k] = std::min(a[k], b[k]);
            return a;
        });
    for (int a = 0; a < 3; ++a) lo_[a] = lo[a];
    table_size_ = std::max<uint64_t>(n, 1);
    cell_starts_.assign(table_size_ + 1, 0);
    indices_.resize(n);
    bucket_of_.resize(n);

    tbb::parallel_for(Range(0, n, kGrain), [&](const Range& r) {
        for (size_t i = r.begin(); i < r.end(); ++i) {
            const Vec3& p = positions[i];
            const uint32_t b =
                hash(cell_coordinate(p.x, 0), cell_coordinate(p.y, 1), cell_coordinate(p.z, 2));
            bucket_of_[i] = b;
            std::atomic_ref<uint32_t>(cell_starts_[b + 1]).fetch_add(1, std::memory_order_relaxed);
        }
    });
    // Inclusive prefix sum over cell_starts_[1..]: integer sums, exact in any grouping.
    tbb::parallel_scan(
        Range(1, table_size_ + 1, kGrain), uint32_t(0),
        [&](const Range& r, uint32_t sum, bool final_pass) {
            for (size_t b = r.begin(); b < r.end(); ++b) {
                sum += cell_starts_[b];
                if (final_pass) cell_starts_[b] = sum;
            }
            return sum;
        },
        [](uint32_t a, uint32_t b) { return a + b; });
    fill_.assign(cell_starts_.begin(), cell_starts_.end() - 1);
    tbb::parallel_for(Range(0, n, kGrain), [&](const Range& r) {
        for (size_t i = r.begin(); i < r.end(); ++i) {
            const uint32_t slot = std::atomic_ref<uint32_t>(fill_[bucket_of_[i]])
                                      .fetch_add(1, std::memory_order_relaxed);
            indices_[slot] = uint32_t(i);
        }
    });
    tbb::parallel_for(Range(0, table_size_, kGrain), [&](const Range& r) {
        for (size_t b = r.begin(); b < r.end(); ++b)
            if (cell_starts_[b + 1] - cell_starts_[b] > 1)
                std::sort(indices_.begin() + cell_starts_[b],
                          indices_.begin() + cell_starts_[b + 1]);
    });
}

}  // namespace render
