// PointsAlongRay (core/integrators/points_along_ray.h) against a linear scan: for fixed-seed
// point sets (uniform in a box, and clustered on a line the rays follow) and rays in every
// direction, including rays along a coordinate axis and segments of length 0 and 1e6, every
// query must visit exactly the points the scan accepts (closest approach at t in
// [t_min, t_max], squared distance <= r^2), each once, with the scan's t and squared distance.
// Points within 1e-4 r of the radius or 1e-4 of a segment end are left out of the comparison
// (the BVH's float bounds may round either way there).

#include "core/integrators/points_along_ray.h"

#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <vector>

#include "core/sampling/rng.h"
#include "core/sampling/warp.h"

namespace render {
namespace {

struct Near {
    float t, distance2;
};

std::map<uint32_t, Near> scan(const std::vector<Vec3>& points, const Ray& ray, float r,
                              std::vector<bool>& borderline) {
    std::map<uint32_t, Near> out;
    borderline.assign(points.size(), false);
    for (uint32_t i = 0; i < points.size(); ++i) {
        const Vec3 op = points[i] - ray.origin;
        const float t = dot(op, ray.direction);
        const float d2 = length_squared(op - ray.direction * t);
        const float d = std::sqrt(d2);
        borderline[i] = std::abs(d - r) < 1e-4f * r || std::abs(t - ray.t_min) < 1e-4f ||
                        std::abs(t - ray.t_max) < 1e-4f;
        if (t >= ray.t_min && t <= ray.t_max && d2 <= r * r) out[i] = Near{t, d2};
    }
    return out;
}

void check_queries(const std::vector<Vec3>& points, float r, const std::vector<Ray>& rays) {
    PointsAlongRay lookup;
    lookup.build(points, r);
    int visited_total = 0;
    for (const Ray& ray : rays) {
        std::vector<bool> borderline;
        const std::map<uint32_t, Near> expected = scan(points, ray, r, borderline);
        std::map<uint32_t, int> visits;
        std::map<uint32_t, Near> got;
        lookup.for_each_near(ray, [&](uint32_t i, float t, float d2) {
            ++visits[i];
            got[i] = Near{t, d2};
        });
        for (const auto& [i, n] : visits) EXPECT_EQ(n, 1) << "point " << i << " visited twice";
        for (const auto& [i, e] : expected) {
            if (borderline[i]) continue;
            auto g = got.find(i);
            ASSERT_NE(g, got.end()) << "point " << i << " missed";
            EXPECT_NEAR(g->second.t, e.t, 1e-5f * (1 + std::abs(e.t)));
            EXPECT_NEAR(g->second.distance2, e.distance2, 1e-5f * r * r);
        }
        for (const auto& [i, g] : got)
            if (!borderline[i]) {
                EXPECT_TRUE(expected.count(i)) << "point " << i << " not near";
            }
        visited_total += int(got.size());
    }
    EXPECT_GE(visited_total, 20);  // the comparison is not vacuous
}

TEST(PointsAlongRay, VisitsExactlyThePointsNearTheSegment) {
    Rng rng(StreamKey{11, 0, 0, 0});
    std::vector<Vec3> uniform(20000);
    for (Vec3& p : uniform)
        p = Vec3(rng.next_1d(), rng.next_1d(), rng.next_1d()) * 4.0f - Vec3(2.0f);
    std::vector<Ray> rays;
    for (int k = 0; k < 200; ++k) {
        const Vec3 o = Vec3(rng.next_1d(), rng.next_1d(), rng.next_1d()) * 4.0f - Vec3(2.0f);
        const Vec3 d = warp::square_to_uniform_sphere(rng.next_2d());
        rays.push_back(Ray(o, d, 0.0f, 0.2f + 3.0f * rng.next_1d()));
    }
    rays.push_back(Ray(Vec3(-2.5f, 0.1f, 0.2f), Vec3(1, 0, 0), 0.0f, 5.0f));  // along an axis
    rays.push_back(Ray(Vec3(0.3f, -2.5f, 0.2f), Vec3(0, 1, 0), 0.0f, 1e6f));  // very long
    for (float r : {0.01f, 0.05f, 0.2f}) check_queries(uniform, r, rays);
}

TEST(PointsAlongRay, ClusteredOnTheRayAndZeroLength) {
    // Points on and beside the x axis; rays along it (parallel to the cluster) and a segment
    // of length 0, which can only find points at its origin's perpendicular plane.
    Rng rng(StreamKey{12, 0, 0, 0});
    std::vector<Vec3> line(5000);
    for (Vec3& p : line)
        p = Vec3(rng.next_1d() * 10.0f - 5.0f, (rng.next_1d() - 0.5f) * 0.02f,
                 (rng.next_1d() - 0.5f) * 0.02f);
    std::vector<Ray> rays = {Ray(Vec3(-6, 0, 0), Vec3(1, 0, 0), 0.0f, 12.0f),
                             Ray(Vec3(-6, 0.004f, 0), Vec3(1, 0, 0), 2.0f, 3.0f),
                             Ray(Vec3(0, 0, -1), Vec3(0, 0, 1), 0.0f, 2.0f)};
    check_queries(line, 0.005f, rays);
    PointsAlongRay lookup;
    lookup.build(line, 0.005f);
    int zero_length_visits = 0;
    lookup.for_each_near(Ray(Vec3(0.1f, 0, 0), Vec3(1, 0, 0), 0.0f, 0.0f),
                         [&](uint32_t i, float t, float) {
                             EXPECT_NEAR(line[i].x, 0.1f, 1e-5f);
                             EXPECT_EQ(t, 0.0f);
                             ++zero_length_visits;
                         });
    EXPECT_LE(zero_length_visits, 1);
}

TEST(PointsAlongRay, EmptyAndRebuilt) {
    PointsAlongRay lookup;
    std::vector<Vec3> none;
    lookup.build(none, 0.1f);
    int visits = 0;
    lookup.for_each_near(Ray(Vec3(0.0f), Vec3(1, 0, 0), 0.0f, 10.0f),
                         [&](uint32_t, float, float) { ++visits; });
    EXPECT_EQ(visits, 0);
    std::vector<Vec3> one = {Vec3(1, 0.05f, 0)};
    lookup.build(one, 0.1f);  // the same object, rebuilt for the next iteration
    lookup.for_each_near(Ray(Vec3(0.0f), Vec3(1, 0, 0), 0.0f, 10.0f),
                         [&](uint32_t i, float t, float d2) {
                             EXPECT_EQ(i, 0u);
                             EXPECT_NEAR(t, 1.0f, 1e-6f);
                             EXPECT_NEAR(d2, 0.0025f, 1e-7f);
                             ++visits;
                         });
    EXPECT_EQ(visits, 1);
}

// bounds() lets upbp skip an eye segment's walk whose line misses it (Iteration::gather_reach):
// every point a query finds, and its projection on the query, lie inside it. Planted, a box
// not grown by the radius leaves projections outside.
TEST(PointsAlongRay, BoundsHoldEveryPointFoundAndItsProjection) {
    Rng rng(StreamKey{13, 0, 0, 0});
    std::vector<Vec3> points(2000);
    for (Vec3& p : points)
        p = Vec3(rng.next_1d(), rng.next_1d(), rng.next_1d()) * 2.0f - Vec3(1.0f);
    for (float r : {0.05f, 0.3f}) {
        PointsAlongRay lookup;
        lookup.build(points, r, 500);  // a prefix, as query beams index one
        const Aabb box = lookup.bounds();
        ASSERT_FALSE(box.empty());
        int found = 0;
        for (int k = 0; k < 1000; ++k) {
            const Vec3 o = Vec3(rng.next_1d(), rng.next_1d(), rng.next_1d()) * 4.0f - Vec3(2.0f);
            const Ray ray(o, warp::square_to_uniform_sphere(rng.next_2d()), 0.0f, 4.0f);
            lookup.for_each_near(ray, [&](uint32_t i, float t, float) {
                EXPECT_LT(i, 500u);
                for (const Vec3& x : {points[i], ray.at(t)})
                    for (int axis = 0; axis < 3; ++axis) {
                        EXPECT_GE(x[axis], box.lo[axis]);
                        EXPECT_LE(x[axis], box.hi[axis]);
                    }
                ++found;
            });
        }
        EXPECT_GE(found, 50) << r;
    }
    PointsAlongRay empty;
    empty.build(points, 0.1f, 0);
    EXPECT_TRUE(empty.bounds().empty());
}

}  // namespace
}  // namespace render
