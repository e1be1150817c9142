#include "core/integrators/importance_lookup.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace render {

double ic_record_distance(const Vec3& x, const Vec3& n_x, const IcRecordPoint& r, double lambda) {
    const double dx = double(x.x) - r.position.x, dy = double(x.y) - r.position.y,
                 dz = double(x.z) - r.position.z;
    const double cosine =
        double(n_x.x) * r.normal.x + double(n_x.y) * r.normal.y + double(n_x.z) * r.normal.z;
    // |cos|: the records' normals face their viewers but a shading point's is the surface's
    // own, which may face either way (importance_lookup.h).
    return std::sqrt(dx * dx + dy * dy + dz * dz) +
           lambda * std::sqrt(std::max(0.0, 1 - std::abs(cosine)));
}

bool ic_record_faces(const IcRecordPoint& r, const Vec3& x, double behind_slack) {
    if (!(behind_slack < std::numeric_limits<double>::infinity())) return true;
    const double dx = double(x.x) - r.position.x, dy = double(x.y) - r.position.y,
                 dz = double(x.z) - r.position.z;
    const double along = dx * r.normal.x + dy * r.normal.y + dz * r.normal.z;
    return along >= -behind_slack * std::sqrt(dx * dx + dy * dy + dz * dz);
}

namespace {

// (d, index) lexicographic: the total order both lookups use.
bool before(double d, uint32_t i, double d_other, uint32_t i_other) {
    return d < d_other || (d == d_other && i < i_other);
}

// Inserts record i at distance d into the sorted list of at most `count` entries.
void offer(IcNeighbours& best, int count, uint32_t i, double d) {
    if (best.count == count && !before(d, i, best.distance[count - 1], best.index[count - 1]))
        return;
    int k = std::min(best.count, count - 1);  // slot to fill, then bubble toward the front
    while (k > 0 && before(d, i, best.distance[k - 1], best.index[k - 1])) {
        best.distance[k] = best.distance[k - 1];
        best.index[k] = best.index[k - 1];
        --k;
    }
    best.distance[k] = d;
    best.index[k] = i;
    best.count = std::min(best.count + 1, count);
}

int clamp_count(const IcLookupSettings& s) {
    return std::clamp(s.count, 0, kIcMaxRecords);
}

bool usable(double d, const IcLookupSettings& s) {
    return std::isfinite(d) && d <= s.max_distance;
}

}  // namespace

IcNeighbours ic_nearest_records_brute_force(std::span<const IcRecordPoint> records, const Vec3& x,
                                            const Vec3& n_x, const IcLookupSettings& settings) {
    IcNeighbours best;
    const int count = clamp_count(settings);
    if (count == 0) return best;
    for (size_t i = 0; i < records.size(); ++i) {
        if (!ic_record_faces(records[i], x, settings.behind_slack)) continue;
        const double d = ic_record_distance(x, n_x, records[i], settings.lambda);
        if (usable(d, settings)) offer(best, count, uint32_t(i), d);
    }
    return best;
}

IcRecordTree::IcRecordTree(std::vector<IcRecordPoint> records) : records_(std::move(records)) {
    order_.resize(records_.size());
    for (uint32_t i = 0; i < order_.size(); ++i) order_[i] = i;
    if (!records_.empty()) build(0, uint32_t(records_.size()));
}

int32_t IcRecordTree::build(uint32_t begin, uint32_t end) {
    constexpr uint32_t kLeafSize = 8;
    Node node;
    node.lo = node.hi = records_[order_[begin]].position;
    for (uint32_t k = begin; k < end; ++k) {
        node.lo = min(node.lo, records_[order_[k]].position);
        node.hi = max(node.hi, records_[order_[k]].position);
    }
    node.begin = begin;
    node.end = end;
    const int32_t id = int32_t(nodes_.size());
    nodes_.push_back(node);
    if (end - begin <= kLeafSize) return id;
    const Vec3 extent = node.hi - node.lo;
    const int axis =
        extent.x >= extent.y && extent.x >= extent.z ? 0 : (extent.y >= extent.z ? 1 : 2);
    const uint32_t mid = begin + (end - begin) / 2;
    std::nth_element(order_.begin() + begin, order_.begin() + mid, order_.begin() + end,
                     [&](uint32_t a, uint32_t b) {
                         return records_[a].position[axis] < records_[b].position[axis];
                     });
    const int32_t left = build(begin, mid);
    const int32_t right = build(mid, end);
    nodes_[id].left = left;
    nodes_[id].right = right;
    return id;
}

namespace {

// Squared distance from x to the box [lo, hi], in double.
double box_distance2(const Vec3& x, const Vec3& lo, const Vec3& hi) {
    double sum = 0;
    for (int a = 0; a < 3; ++a) {
        const double gap = std::max({double(lo[a]) - x[a], double(x[a]) - hi[a], 0.0});
        sum += gap * gap;
    }
    return sum;
}

// Whether everything at squared position distance >= `bound2` is strictly farther than `d`
// (d(x, r) >= |x - r|), with a relative margin for the rounding of the square roots, so that a
// record whose d might tie with or beat `d` is never skipped.
bool farther(double bound2, double d) {
    return bound2 * (1 - 1e-12) > d * d;
}

}  // namespace

// The lookup runs at every shading point (bpt: every eye vertex), so it compares squared
// distances and skips a record by its position alone before computing d: every skip is one
// the result does not depend on (`farther`), so the tree still equals the brute force.
void IcRecordTree::search(int32_t id, double bound2, const Vec3& x, const Vec3& n_x,
                          const IcLookupSettings& settings, int count, IcNeighbours& best) const {
    if (farther(bound2, settings.max_distance)) return;
    if (best.count == count && farther(bound2, best.distance[count - 1])) return;
    const Node& node = nodes_[id];
    if (node.left < 0) {
        for (uint32_t k = node.begin; k < node.end; ++k) {
            const uint32_t i = order_[k];
            const IcRecordPoint& r = records_[i];
            if (best.count == count) {
                const double dx = double(x.x) - r.position.x, dy = double(x.y) - r.position.y,
                             dz = double(x.z) - r.position.z;
                if (farther(dx * dx + dy * dy + dz * dz, best.distance[count - 1])) continue;
            }
            if (!ic_record_faces(r, x, settings.behind_slack)) continue;
            const double d = ic_record_distance(x, n_x, r, settings.lambda);
            if (usable(d, settings)) offer(best, count, i, d);
        }
        return;
    }
    // Nearer child first, so the bound tightens early.
    const Node& l = nodes_[node.left];
    const Node& r = nodes_[node.right];
    const double bl = box_distance2(x, l.lo, l.hi), br = box_distance2(x, r.lo, r.hi);
    if (bl <= br) {
        search(node.left, bl, x, n_x, settings, count, best);
        search(node.right, br, x, n_x, settings, count, best);
    } else {
        search(node.right, br, x, n_x, settings, count, best);
        search(node.left, bl, x, n_x, settings, count, best);
    }
}

IcNeighbours IcRecordTree::nearest(const Vec3& x, const Vec3& n_x,
                                   const IcLookupSettings& settings) const {
    IcNeighbours best;
    const int count = clamp_count(settings);
    if (nodes_.empty() || count == 0) return best;
    search(0, box_distance2(x, nodes_[0].lo, nodes_[0].hi), x, n_x, settings, count, best);
    return best;
}

}  // namespace render
