#include "server/interval_set.h"

#include <algorithm>

namespace render::server {

void IntervalSet::add(Range r) {
    if (r.size() == 0) return;
    uint64_t first = r.first, end = r.end;
    auto it = ranges_.upper_bound(first);
    if (it != ranges_.begin()) {
        auto prev = std::prev(it);
        if (prev->second >= first) {
            first = prev->first;
            end = std::max(end, prev->second);
            it = ranges_.erase(prev);
        }
    }
    while (it != ranges_.end() && it->first <= end) {
        end = std::max(end, it->second);
        it = ranges_.erase(it);
    }
    ranges_[first] = end;
}

void IntervalSet::subtract(Range r) {
    if (r.size() == 0) return;
    auto it = ranges_.upper_bound(r.first);
    if (it != ranges_.begin()) --it;
    std::vector<Range> keep;
    while (it != ranges_.end() && it->first < r.end) {
        Range cur{it->first, it->second};
        if (cur.end <= r.first) {
            ++it;
            continue;
        }
        it = ranges_.erase(it);
        if (cur.first < r.first) keep.push_back({cur.first, r.first});
        if (cur.end > r.end) keep.push_back({r.end, cur.end});
    }
    for (const Range& k : keep) ranges_[k.first] = k.end;
}

bool IntervalSet::overlaps(Range r) const {
    if (r.size() == 0) return false;
    auto it = ranges_.lower_bound(r.end);  // first range starting at or after r.end
    if (it == ranges_.begin()) return false;
    --it;  // the last range starting before r.end
    return it->second > r.first;
}

bool IntervalSet::contains(Range r) const {
    if (r.size() == 0) return true;
    auto it = ranges_.upper_bound(r.first);
    if (it == ranges_.begin()) return false;
    --it;
    return it->first <= r.first && it->second >= r.end;
}

uint64_t IntervalSet::total() const {
    uint64_t n = 0;
    for (const auto& [first, end] : ranges_) n += end - first;
    return n;
}

uint64_t IntervalSet::max_end(uint64_t fallback) const {
    return ranges_.empty() ? fallback : ranges_.rbegin()->second;
}

std::optional<Range> IntervalSet::first() const {
    if (ranges_.empty()) return std::nullopt;
    return Range{ranges_.begin()->first, ranges_.begin()->second};
}

std::vector<Range> IntervalSet::ranges() const {
    std::vector<Range> out;
    out.reserve(ranges_.size());
    for (const auto& [first, end] : ranges_) out.push_back({first, end});
    return out;
}

}  // namespace render::server
