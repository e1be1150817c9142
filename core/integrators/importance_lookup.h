#pragma once

// Which importance records a shading point uses (section 2.3): the R nearest by
//     d(x, r) = |x - r| + lambda * sqrt(max(0, 1 - |n_x . n_r|)),   lambda = 0.5 * D,
// D the scene's diameter, R = 3. Ties in d are broken by the lower record index, so the choice
// is a deterministic function of the inputs (the iteration contract).
//
// The spec restates the thesis' weight as lambda = 0.5 / D, which has units 1/length while
// |x - r| is a length: the choice would then change with the scene's unit (a scene in
// millimetres would rank by position alone, the same scene in kilometres by normal alone).
// The reading that keeps d a length is the thesis' distance with the position divided by D,
// |x - r| / D + 0.5 sqrt(1 - n_x . n_r), which ranks records exactly as lambda = 0.5 * D does
// here. With it the choice is invariant under scaling the scene (tested), and a record whose
// normal differs by 90 degrees is as far as one half a diameter away: a shading point prefers
// records on its own surface, whose tables see the VPLs it sees (a concave corner's ceiling
// point otherwise takes the wall's records, which see a VPL on the wall edge-on; only the
// uniform table C then draws it, the heavy tail of ic's variance on scenes/claims/ic-rooms.xml,
// docs/results/claims.md).
//
// |n_x . n_r|, not the signed cosine: a record's normal faces the side it was seen from, but the
// shading point's is its surface's geometric normal, which faces away from the viewer on half
// the surfaces of a scene (a room's walls modelled with outward normals); with the signed
// cosine every record on x's own surface would then be lambda * sqrt(2) away and a record on a
// perpendicular surface nearer. Which side x is on is the behind test's job (below).
//
// A record is usable when d(x, r) <= max_distance (default: any) and x is not behind the
// record's surface: (x - r) . n_r >= -behind_slack * |x - r|, with n_r facing the side the record
// was seen from. A record's tables describe the light arriving at the front of its surface; a
// shading point just behind it (the other side of a thin wall, a point around a corner) is
// lit by VPLs the record cannot see even unoccluded (U and B are 0 for VPLs behind the
// record's plane), so with such records only C covers them, with pmf 1 / M: the rare draws of a
// bright VPL there carry weight M / n and dominate the variance (docs/design/algorithms-next.md
// 2.3; measured on scenes/claims/ic-rooms.xml, the doorways' far side). Which records x uses
// never biases the estimator (C covers every VPL); it only shapes the variance.
// With none usable the shading point gets no records and IcMixture falls back to C over all VPLs
// (uniform VPL sampling, unbiased; pg2015 skipped the connection there, which loses energy).

#include <array>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <span>
#include <vector>

#include "core/integrators/importance_mixture.h"
#include "core/math/vec.h"

namespace render {

struct IcRecordPoint {
    Vec3 position;
    Vec3 normal;  // unit; shading normal of the record's surface, facing the side it was seen
                  // from (zero in a medium: no side)
};

struct IcLookupSettings {
    int count = 3;      // R, at most kIcMaxRecords
    double lambda = 0;  // weight of the normal term (ic_default_lambda)
    double max_distance = std::numeric_limits<double>::infinity();
    // x may lie this far behind a record's tangent plane, relative to |x - r| (0.1: about 6
    // degrees, for curved surfaces and the rounding of coplanar points); infinity: no test.
    double behind_slack = 0.1;
};

// Whether x is in front of the record's surface in the sense above.
bool ic_record_faces(const IcRecordPoint& r, const Vec3& x, double behind_slack);

inline double ic_default_lambda(double scene_diameter) {
    return scene_diameter > 0 ? 0.5 * scene_diameter : 0.0;
}

// d(x, r) above, in double.
double ic_record_distance(const Vec3& x, const Vec3& n_x, const IcRecordPoint& r, double lambda);

// The chosen records, nearest first (by d, then index). count == 0: use the fallback.
struct IcNeighbours {
    std::array<uint32_t, kIcMaxRecords> index{};
    std::array<double, kIcMaxRecords> distance{};
    int count = 0;
};

// Reference: every record's d, O(records) per query.
IcNeighbours ic_nearest_records_brute_force(std::span<const IcRecordPoint> records, const Vec3& x,
                                            const Vec3& n_x, const IcLookupSettings& settings);

// The same result (tested against the brute force) from a k-d tree over the positions,
// pruning subtrees whose box is farther than the current R-th best d (valid since
// d(x, r) >= |x - r|).
class IcRecordTree {
  public:
    IcRecordTree() = default;
    explicit IcRecordTree(std::vector<IcRecordPoint> records);

    size_t size() const { return records_.size(); }
    const IcRecordPoint& record(size_t i) const { return records_[i]; }
    IcNeighbours nearest(const Vec3& x, const Vec3& n_x, const IcLookupSettings& settings) const;

  private:
    struct Node {
        Vec3 lo, hi;         // bounds of the node's positions
        uint32_t begin = 0;  // range of order_ (leaves)
        uint32_t end = 0;
        int32_t left = -1;  // children (inner nodes), -1 for a leaf
        int32_t right = -1;
    };
    int32_t build(uint32_t begin, uint32_t end);
    // bound2: the squared distance from x to the node's box.
    void search(int32_t node, double bound2, const Vec3& x, const Vec3& n_x,
                const IcLookupSettings& settings, int count, IcNeighbours& best) const;

    std::vector<IcRecordPoint> records_;
    std::vector<uint32_t> order_;  // record indices, grouped by leaf
    std::vector<Node> nodes_;
};

}  // namespace render
