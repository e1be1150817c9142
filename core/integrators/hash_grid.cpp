#include "core/integrators/hash_grid.h"

#include <algorithm>
#include <limits>

namespace render {

void HashGrid::build(const std::vector<Vec3>& positions, double radius) {
    positions_ = &positions;
    radius2_ = float(radius * radius);
    inv_cell_size_ = 1.0 / (2.0 * radius);
    for (int a = 0; a < 3; ++a) lo_[a] = std::numeric_limits<double>::infinity();
    for (const Vec3& p : positions)
        for (int a = 0; a < 3; ++a) lo_[a] = std::min(lo_[a], double(p[a]));
    table_size_ = std::max<uint64_t>(positions.size(), 1);
    cell_starts_.assign(table_size_ + 1, 0);
    indices_.resize(positions.size());
    // Counting sort of the points by bucket.
    std::vector<uint32_t> bucket_of(positions.size());
    for (size_t i = 0; i < positions.size(); ++i) {
        const Vec3& p = positions[i];
        bucket_of[i] =
            hash(cell_coordinate(p.x, 0), cell_coordinate(p.y, 1), cell_coordinate(p.z, 2));
        ++cell_starts_[bucket_of[i] + 1];
    }
    for (size_t b = 0; b < table_size_; ++b) cell_starts_[b + 1] += cell_starts_[b];
    std::vector<uint32_t> fill(cell_starts_.begin(), cell_starts_.end() - 1);
    for (size_t i = 0; i < positions.size(); ++i) indices_[fill[bucket_of[i]]++] = uint32_t(i);
}

}  // namespace render
