// HashGrid (core/integrators/hash_grid.h) against a linear scan: for fixed-seed point sets
// (uniform, tightly clustered, duplicated, and placed exactly on cell boundaries and at
// exactly the radius from each other) and several radii, every query must visit exactly the
// points a linear scan accepts, each once. The scan uses the predicate the grid documents,
// |positions[i] - p| <= radius, evaluated as the grid does (float squared distance against
// the float squared radius), so that the comparison is exact.

#include "core/integrators/hash_grid.h"

#include <gtest/gtest.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/sampling/rng.h"

namespace render {
namespace {

// The lower corner of every point set below: the grid's cells start there, at multiples of
// its cell size 2 r.
const Vec3 kLow(-3.0f, -2.0f, -1.0f);

Vec3 random_in(Rng& rng, const Vec3& lo, const Vec3& hi) {
    return {lo.x + (hi.x - lo.x) * rng.next_1d(), lo.y + (hi.y - lo.y) * rng.next_1d(),
            lo.z + (hi.z - lo.z) * rng.next_1d()};
}

// Uniform points in [kLow, kLow + 6], three tight clusters (one of exact duplicates), points
// on the cell boundaries of `radius` and the corner kLow itself.
std::vector<Vec3> point_set(double radius, uint64_t seed) {
    Rng rng(StreamKey{seed, 0, 1, 0});
    const Vec3 hi = kLow + Vec3(6.0f);
    std::vector<Vec3> points = {kLow};
    for (int i = 0; i < 2000; ++i) points.push_back(random_in(rng, kLow, hi));
    const Vec3 centres[] = {kLow + Vec3(1.0f, 1.0f, 1.0f), kLow + Vec3(4.5f, 0.2f, 3.3f)};
    for (const Vec3& c : centres)
        for (int i = 0; i < 300; ++i)
            points.push_back(
                random_in(rng, c - Vec3(float(1e-3 * radius)), c + Vec3(float(1e-3 * radius))));
    for (int i = 0; i < 50; ++i) points.push_back(kLow + Vec3(2.0f, 2.0f, 2.0f));  // duplicates
    // On cell boundaries kLow + k 2r along one, two or three axes.
    const float cell = float(2.0 * radius);
    for (int i = 0; i < 300; ++i) {
        Vec3 p = random_in(rng, kLow, hi);
        const int axes = 1 + i % 7;  // a non-empty subset of {x, y, z}
        for (int a = 0; a < 3; ++a)
            if (axes >> a & 1) {
                const float k = std::floor((p[a] - kLow[a]) / cell);
                p[a] = kLow[a] + k * cell;
            }
        points.push_back(p);
    }
    return points;
}

// Queries: every point itself, random points in and around the set (below kLow too, where
// cell coordinates are negative), points on cell boundaries and at exactly +-radius from a
// point along each axis (where the predicate is decided by rounding).
std::vector<Vec3> query_set(const std::vector<Vec3>& points, double radius, uint64_t seed) {
    Rng rng(StreamKey{seed, 0, 2, 0});
    std::vector<Vec3> queries = points;
    for (int i = 0; i < 1000; ++i)
        queries.push_back(random_in(rng, kLow - Vec3(1.0f), kLow + Vec3(7.0f)));
    const float cell = float(2.0 * radius), r = float(radius);
    for (int i = 0; i < 300; ++i) {
        Vec3 q = random_in(rng, kLow - Vec3(1.0f), kLow + Vec3(7.0f));
        for (int a = 0; a < 3; ++a)
            if (i % 2 == 0 || a == i % 3)
                q[a] = kLow[a] + std::round((q[a] - kLow[a]) / cell) * cell;
        queries.push_back(q);
        // Half-way between boundaries: the query's own cell centre plane.
        Vec3 h = q;
        h[i % 3] += 0.5f * cell;
        queries.push_back(h);
    }
    for (size_t i = 0; i < points.size(); i += 7)
        for (int a = 0; a < 3; ++a)
            for (float s : {-1.0f, 1.0f}) {
                Vec3 q = points[i];
                q[a] += s * r;
                queries.push_back(q);
            }
    return queries;
}

std::vector<uint32_t> linear_scan(const std::vector<Vec3>& points, const Vec3& q, double radius) {
    const float radius2 = float(radius * radius);
    std::vector<uint32_t> within;
    for (size_t i = 0; i < points.size(); ++i)
        if (length_squared(points[i] - q) <= radius2) within.push_back(uint32_t(i));
    return within;
}

void expect_matches_linear_scan(const std::vector<Vec3>& points, double radius, uint64_t seed) {
    HashGrid grid;
    grid.build(points, radius);
    const std::vector<Vec3> queries = query_set(points, radius, seed);
    size_t found = 0, non_trivial = 0;
    for (const Vec3& q : queries) {
        std::vector<uint32_t> visited;
        grid.for_each_within_radius(q, [&](uint32_t i) { visited.push_back(i); });
        std::sort(visited.begin(), visited.end());
        ASSERT_TRUE(std::adjacent_find(visited.begin(), visited.end()) == visited.end())
            << "a point visited twice for query " << q;
        const std::vector<uint32_t> expected = linear_scan(points, q, radius);
        ASSERT_EQ(visited, expected) << "query " << q << ", radius " << radius << ": grid "
                                     << visited.size() << " points, scan " << expected.size();
        found += expected.size();
        non_trivial += expected.size() > 1;
    }
    // The query set is not vacuous: many queries find several points.
    EXPECT_GT(non_trivial, queries.size() / 10) << "radius " << radius;
    EXPECT_GT(found, queries.size()) << "radius " << radius;
}

// Radii from much smaller than the point spacing (only clusters and duplicates share a
// neighbourhood) to larger than the whole set (which then falls into a few cells of size 2r,
// so every query scans almost every point). 0.25 makes the boundaries exact in float; 0.1 and
// 0.0137 do not.
TEST(HashGrid, MatchesLinearScan) {
    uint64_t seed = 1;
    for (double radius : {0.0137, 0.1, 0.25, 0.7, 8.0}) {
        SCOPED_TRACE(::testing::Message() << "radius " << radius);
        expect_matches_linear_scan(point_set(radius, seed), radius, seed);
        ++seed;
    }
}

// Far from the origin, where float spacing is coarse relative to the radius.
TEST(HashGrid, MatchesLinearScanFarFromTheOrigin) {
    std::vector<Vec3> points = point_set(0.25, 11);
    for (Vec3& p : points) p += Vec3(1000.0f, -500.0f, 250.0f);
    HashGrid grid;
    grid.build(points, 0.25);
    Rng rng(StreamKey{12, 0, 1, 0});
    for (size_t i = 0; i < points.size(); ++i) {
        const Vec3 q = points[i] + Vec3(0.3f * (rng.next_1d() - 0.5f), 0.0f, 0.0f);
        std::vector<uint32_t> visited;
        grid.for_each_within_radius(q, [&](uint32_t j) { visited.push_back(j); });
        std::sort(visited.begin(), visited.end());
        ASSERT_EQ(visited, linear_scan(points, q, 0.25)) << "query " << q;
    }
}

TEST(HashGrid, EmptyAndSinglePointSets) {
    std::vector<Vec3> none;
    HashGrid grid;
    grid.build(none, 1.0);
    int calls = 0;
    grid.for_each_within_radius(Vec3(0.0f), [&](uint32_t) { ++calls; });
    EXPECT_EQ(calls, 0);
    HashGrid unbuilt;
    unbuilt.for_each_within_radius(Vec3(0.0f), [&](uint32_t) { ++calls; });
    EXPECT_EQ(calls, 0);

    std::vector<Vec3> one = {Vec3(1, 2, 3)};
    grid.build(one, 0.5);
    std::vector<uint32_t> visited;
    grid.for_each_within_radius(Vec3(1.4f, 2, 3), [&](uint32_t i) { visited.push_back(i); });
    EXPECT_EQ(visited, std::vector<uint32_t>{0});
    visited.clear();
    grid.for_each_within_radius(Vec3(1.6f, 2, 3), [&](uint32_t i) { visited.push_back(i); });
    EXPECT_TRUE(visited.empty());
}

// The grid is built in parallel, but every cell's points are visited in increasing index order
// whatever the number of threads (the merge sums visits in that order: images must not depend
// on the thread count). 240000 points, a third of them at one position (one cell, whose points
// come from every block of the build's parallel passes), the rest uniform; builds with 2 and 4
// threads are repeated, as scheduling differs from run to run.
TEST(HashGrid, VisitOrderIsIncreasingAndIndependentOfTheThreadCount) {
    Rng rng(StreamKey{21, 0, 1, 0});
    const Vec3 shared(1.0f, 1.0f, 1.0f);
    std::vector<Vec3> points;
    for (int i = 0; i < 240000; ++i)
        points.push_back(i % 3 == 0 ? shared : random_in(rng, kLow, kLow + Vec3(6.0f)));
    const double radius = 0.05;
    std::vector<Vec3> queries = {shared};
    for (int i = 0; i < 2000; ++i) queries.push_back(points[size_t(i) * 113]);
    auto visits = [&](int threads) {
        HashGrid grid;
        tbb::task_arena(threads).execute([&] { grid.build(points, radius); });
        std::vector<std::vector<uint32_t>> all;
        for (const Vec3& q : queries) {
            all.emplace_back();
            grid.for_each_within_radius(q, [&](uint32_t i) { all.back().push_back(i); });
        }
        return all;
    };
    const auto one = visits(1);
    // The shared position's points are one cell's: visited in increasing order, all of them.
    std::vector<uint32_t> at_shared;
    for (uint32_t i : one[0])
        if (points[i] == shared) at_shared.push_back(i);
    EXPECT_EQ(at_shared.size(), 80000u);
    EXPECT_TRUE(std::is_sorted(at_shared.begin(), at_shared.end()));
    for (int threads : {2, 4}) {
        for (int repeat = 0; repeat < 5; ++repeat) {
            const auto many = visits(threads);
            ASSERT_EQ(many.size(), one.size());
            for (size_t q = 0; q < one.size(); ++q)
                ASSERT_EQ(many[q], one[q]) << threads << " threads, query " << q;
        }
    }
}

// Ids given to build() are what the visit receives, and the visiting order stays that of the
// point indices (VCM passes each point's increasing light-vertex index: its merge sums must not
// change order). A wrong count of ids is refused by name.
TEST(HashGrid, VisitsTheIdsGivenToTheBuildInPointOrder) {
    const double radius = 0.1;
    const std::vector<Vec3> points = point_set(radius, 31);
    std::vector<uint32_t> ids(points.size());
    for (size_t i = 0; i < ids.size(); ++i) ids[i] = uint32_t(3 * i + 7);  // increasing
    HashGrid plain, with_ids;
    plain.build(points, radius);
    with_ids.build(points, radius, ids);
    size_t non_trivial = 0;
    for (const Vec3& q : query_set(points, radius, 32)) {
        std::vector<uint32_t> expected, visited;
        plain.for_each_within_radius(q, [&](uint32_t i) { expected.push_back(ids[i]); });
        with_ids.for_each_within_radius(q, [&](uint32_t id) { visited.push_back(id); });
        ASSERT_EQ(visited, expected) << "query " << q;
        non_trivial += expected.size() > 1;
    }
    EXPECT_GT(non_trivial, 100u);
    std::vector<uint32_t> too_few(points.size() - 1);
    try {
        with_ids.build(points, radius, too_few);
        FAIL() << "a wrong number of ids was accepted";
    } catch (const std::invalid_argument& e) {
        EXPECT_NE(std::string(e.what()).find("ids"), std::string::npos) << e.what();
    }
}

// A grid built from a position callback (as the light pass builds it from its light vertices,
// through their ids) visits what one built from the same positions in an array does, in order.
TEST(HashGrid, PositionCallbackBuildsTheSameGrid) {
    const double radius = 0.1;
    const std::vector<Vec3> points = point_set(radius, 41);
    // The records hold the points in another order; ids map grid point i to its record.
    std::vector<Vec3> records(points.size());
    std::vector<uint32_t> ids(points.size());
    for (size_t i = 0; i < points.size(); ++i) {
        ids[i] = uint32_t(points.size() - 1 - i);
        records[ids[i]] = points[i];
    }
    HashGrid from_array, from_callback;
    from_array.build(points, radius, ids);
    size_t reads = 0;
    from_callback.build(
        points.size(),
        [&](size_t i) {
            ++reads;
            return records[ids[i]];
        },
        radius, ids);
    EXPECT_GE(reads, points.size());
    size_t non_trivial = 0;
    for (const Vec3& q : query_set(points, radius, 42)) {
        std::vector<uint32_t> expected, visited;
        from_array.for_each_within_radius(q, [&](uint32_t id) { expected.push_back(id); });
        from_callback.for_each_within_radius(q, [&](uint32_t id) { visited.push_back(id); });
        ASSERT_EQ(visited, expected) << "query " << q;
        non_trivial += expected.size() > 1;
    }
    EXPECT_GT(non_trivial, 100u);
}

// The two-step visit (prefetch every point found, then visit them) visits what the one-step
// visit does, in the same order, and prefetches each point once before its visit, also when a
// query finds more points than its buffer holds (radius 8: every query finds thousands).
TEST(HashGrid, PrefetchingVisitMatchesThePlainVisitInOrder) {
    for (double radius : {0.1, 8.0}) {
        const std::vector<Vec3> points = point_set(radius, 41);
        HashGrid grid;
        grid.build(points, radius);
        size_t large = 0;
        for (const Vec3& q : query_set(points, radius, 42)) {
            std::vector<uint32_t> plain, prefetched, visited;
            grid.for_each_within_radius(q, [&](uint32_t i) { plain.push_back(i); });
            grid.for_each_within_radius(
                q, [&](uint32_t i) { prefetched.push_back(i); },
                [&](uint32_t i) {
                    ASSERT_GT(prefetched.size(), visited.size()) << "visited before prefetched";
                    visited.push_back(i);
                });
            ASSERT_EQ(visited, plain) << "query " << q << ", radius " << radius;
            ASSERT_EQ(prefetched, plain) << "query " << q << ", radius " << radius;
            large += plain.size() > 32;
        }
        if (radius > 1) {
            EXPECT_GT(large, 100u);
        }
    }
}

// The cells a query skips (out of the sphere's reach) never hold a point within the radius:
// queries at exactly r from a point along one, two and three axes' diagonals, where the point
// sits just across a cell edge or corner from the query, find it as the linear scan does.
TEST(HashGrid, SkippedCellsHoldNoPointWithinTheRadius) {
    const double radius = 0.25;  // cells of 0.5: boundaries exact in float
    const float cell = float(2 * radius);
    std::vector<Vec3> points;
    for (int i = 0; i < 8; ++i)
        for (int j = 0; j < 8; ++j)
            for (int k = 0; k < 8; ++k) points.push_back(kLow + Vec3(i, j, k) * cell);
    HashGrid grid;
    grid.build(points, radius);
    size_t found = 0;
    for (const Vec3& corner : points)
        for (int axes = 1; axes < 8; ++axes)
            for (float scale : {0.999f, 1.0f, 1.001f}) {
                // Toward the corner from inside the neighbouring cell, along the diagonal of
                // the stepped axes, at (about) the radius.
                const int n = (axes & 1) + (axes >> 1 & 1) + (axes >> 2 & 1);
                const float offset = scale * float(radius) / std::sqrt(float(n));
                Vec3 q = corner;
                for (int a = 0; a < 3; ++a)
                    if (axes >> a & 1) q[a] += offset;
                std::vector<uint32_t> visited;
                grid.for_each_within_radius(q, [&](uint32_t i) { visited.push_back(i); });
                std::sort(visited.begin(), visited.end());
                ASSERT_EQ(visited, linear_scan(points, q, radius)) << "query " << q;
                found += visited.size();
            }
    EXPECT_GT(found, points.size() * 7);  // the 0.999 queries find their corner at least
}

}  // namespace
}  // namespace render
