#pragma once

// A set of disjoint half-open ranges [first, end) of iteration indices, kept merged and sorted.

#include <cstdint>
#include <map>
#include <optional>
#include <vector>

namespace render::server {

struct Range {
    uint64_t first = 0;
    uint64_t end = 0;  // exclusive
    uint64_t size() const { return end > first ? end - first : 0; }
    bool operator==(const Range&) const = default;
};

class IntervalSet {
  public:
    // Adds [r.first, r.end); joins touching and overlapping ranges.
    void add(Range r);
    // Removes [r.first, r.end) wherever it is present.
    void subtract(Range r);
    bool overlaps(Range r) const;
    // True if every index of r is in the set.
    bool contains(Range r) const;
    bool empty() const { return ranges_.empty(); }
    // Total number of indices.
    uint64_t total() const;
    // The end of the last range, or `fallback` when empty.
    uint64_t max_end(uint64_t fallback) const;
    // The lowest range, if any.
    std::optional<Range> first() const;
    std::vector<Range> ranges() const;
    void clear() { ranges_.clear(); }

  private:
    std::map<uint64_t, uint64_t> ranges_;  // first -> end
};

}  // namespace render::server
