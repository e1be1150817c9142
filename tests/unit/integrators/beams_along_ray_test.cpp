// BeamsAlongRay (core/integrators/beams_along_ray.h), the lookup of upbp's photon beams, against
// a linear scan, and closest_approach against its definition. Fixed-seed beams (uniform in a
// box, of random lengths including 0 and 1e6, and beams parallel to the rays) and rays in every
// direction: every query must visit exactly the beams the scan accepts (closest approach at
// t_ray in [t_min, t_max] and t_beam in [0, length], within r, not parallel), each once, with
// the scan's parameters. Beams within 1e-3 of the radius or of a range end are left out of the
// comparison (the BVH's float bounds may round either way there).

#include "core/integrators/beams_along_ray.h"

#include "core/integrators/beam_grid.h"

#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <vector>

#include "core/integrators/bidirectional/vcm_mis.h"
#include "core/sampling/rng.h"
#include "core/sampling/warp.h"

namespace render {
namespace {

Vec3 random_point(Rng& rng) {
    return Vec3(rng.next_1d(), rng.next_1d(), rng.next_1d()) * 4.0f - Vec3(2.0f);
}

std::map<uint32_t, BeamApproach> scan(const std::vector<BeamLine>& beams, const Ray& ray, float r,
                                      std::vector<bool>& borderline) {
    std::map<uint32_t, BeamApproach> out;
    borderline.assign(beams.size(), false);
    for (uint32_t i = 0; i < beams.size(); ++i) {
        BeamApproach a;
        if (!closest_approach(ray, beams[i], a)) continue;
        const float eps = 1e-3f;
        borderline[i] = std::abs(a.distance - r) < eps * r || std::abs(a.t_ray - ray.t_min) < eps ||
                        std::abs(a.t_ray - ray.t_max) < eps || std::abs(a.t_beam) < eps ||
                        std::abs(a.t_beam - beams[i].length) < eps ||
                        std::abs(a.sin_theta * a.sin_theta - 1e-5f) < 1e-6f;
        if (a.t_ray >= ray.t_min && a.t_ray <= ray.t_max && a.t_beam >= 0 &&
            a.t_beam <= beams[i].length && a.distance <= r)
            out[i] = a;
    }
    return out;
}

template <typename Lookup>
int check_queries(const Lookup& lookup, const std::vector<BeamLine>& beams, float r,
                  const std::vector<Ray>& rays) {
    int visited_total = 0;
    for (const Ray& ray : rays) {
        std::vector<bool> borderline;
        const std::map<uint32_t, BeamApproach> expected = scan(beams, ray, r, borderline);
        std::map<uint32_t, int> visits;
        std::map<uint32_t, BeamApproach> got;
        lookup.for_each_near(ray, [&](uint32_t i, const BeamApproach& a) {
            ++visits[i];
            got[i] = a;
        });
        for (const auto& [i, n] : visits) EXPECT_EQ(n, 1) << "beam " << i << " visited twice";
        for (const auto& [i, e] : expected) {
            if (borderline[i]) continue;
            auto g = got.find(i);
            if (g == got.end()) {
                ADD_FAILURE() << "beam " << i << " missed";
                continue;
            }
            EXPECT_NEAR(g->second.t_ray, e.t_ray, 1e-4f * (1 + std::abs(e.t_ray)));
            EXPECT_NEAR(g->second.t_beam, e.t_beam, 1e-4f * (1 + std::abs(e.t_beam)));
            EXPECT_NEAR(g->second.distance, e.distance, 1e-4f);
        }
        for (const auto& [i, g] : got)
            if (!borderline[i]) {
                EXPECT_TRUE(expected.count(i)) << "beam " << i << " not near";
            }
        visited_total += int(got.size());
    }
    return visited_total;
}

// closest_approach: the two points it names are at the distance it gives, the segment between
// them is perpendicular to both lines, and no nearby pair of parameters is closer.
TEST(BeamsAlongRay, ClosestApproachIsTheClosestPair) {
    Rng rng(StreamKey{21, 0, 0, 0});
    int checked = 0;
    for (int k = 0; k < 2000; ++k) {
        const Ray ray(random_point(rng), warp::square_to_uniform_sphere(rng.next_2d()));
        const BeamLine beam{random_point(rng), warp::square_to_uniform_sphere(rng.next_2d()), 1};
        BeamApproach a;
        if (!closest_approach(ray, beam, a)) continue;
        const Vec3 p = ray.at(a.t_ray), q = beam.origin + beam.direction * a.t_beam;
        EXPECT_NEAR(length(p - q), a.distance, 1e-4f);
        EXPECT_NEAR(a.sin_theta, length(cross(ray.direction, beam.direction)), 1e-5f);
        if (a.distance > 1e-3f) {
            EXPECT_NEAR(dot(normalize(p - q), ray.direction), 0.0f, 1e-3f);
            EXPECT_NEAR(dot(normalize(p - q), beam.direction), 0.0f, 1e-3f);
        }
        for (float dt : {-0.01f, 0.01f}) {
            EXPECT_GE(length(ray.at(a.t_ray + dt) - q), a.distance - 1e-5f);
            EXPECT_GE(length(p - (beam.origin + beam.direction * (a.t_beam + dt))),
                      a.distance - 1e-5f);
        }
        ++checked;
    }
    EXPECT_GT(checked, 1900);
    // Parallel lines have no single closest approach: refused, with the predicate the MIS
    // weights use for the technique's support.
    BeamApproach a;
    EXPECT_FALSE(closest_approach(Ray(Vec3(0.0f), Vec3(1, 0, 0)),
                                  BeamLine{Vec3(0, 0.01f, 0), Vec3(-1, 0, 0), 1}, a));
    const Vec3 nearly = normalize(Vec3(1, 1e-3f, 0));
    EXPECT_FALSE(closest_approach(Ray(Vec3(0.0f), Vec3(1, 0, 0)),
                                  BeamLine{Vec3(0, 0.01f, 0), nearly, 1}, a));
    EXPECT_TRUE(VcmMis::beams_parallel(length(cross(Vec3(1, 0, 0), nearly))));
}

TEST(BeamsAlongRay, VisitsExactlyTheBeamsNearTheSegment) {
    Rng rng(StreamKey{22, 0, 0, 0});
    std::vector<BeamLine> beams(4000);
    for (BeamLine& b : beams)
        b = BeamLine{random_point(rng), warp::square_to_uniform_sphere(rng.next_2d()),
                     3.0f * rng.next_1d() * rng.next_1d()};
    // Hard cases among them: length 0 (a point: it never matches a line), length 1e6, and
    // beams parallel and anti-parallel to the axis rays below.
    beams[0].length = 0;
    beams[1].length = 1e6f;
    beams[2] = BeamLine{Vec3(-1, 0.1f, 0.2f), Vec3(1, 0, 0), 2};
    beams[3] = BeamLine{Vec3(1, 0.1f, 0.21f), Vec3(-1, 0, 0), 2};
    std::vector<Ray> rays;
    for (int k = 0; k < 200; ++k)
        rays.push_back(Ray(random_point(rng), warp::square_to_uniform_sphere(rng.next_2d()), 0.0f,
                           0.2f + 3.0f * rng.next_1d()));
    rays.push_back(Ray(Vec3(-2.5f, 0.1f, 0.2f), Vec3(1, 0, 0), 0.0f, 5.0f));  // along an axis
    rays.push_back(Ray(Vec3(0.3f, -2.5f, 0.2f), Vec3(0, 1, 0), 0.0f, 1e6f));  // very long
    for (float r : {0.01f, 0.05f, 0.2f}) {
        BeamsAlongRay lookup;
        lookup.build(beams, r);
        EXPECT_GE(check_queries(lookup, beams, r, rays), 20) << r;
    }
}

// The uniform grid (beam_grid.h, the integrator's lookup when every beam is inside the scene's
// box) against the same scan: random beams and segments inside its bounds, several cell sizes
// (cells per beam), each beam visited once; and with bounds of 1e6 for the hard cases below.
TEST(UniformBeamGrid, VisitsExactlyTheBeamsNearTheSegment) {
    Rng rng(StreamKey{23, 0, 0, 0});
    std::vector<BeamLine> beams(4000);
    for (BeamLine& b : beams)
        b = BeamLine{random_point(rng), warp::square_to_uniform_sphere(rng.next_2d()),
                     3.0f * rng.next_1d() * rng.next_1d()};
    beams[0].length = 0;
    beams[2] = BeamLine{Vec3(-1, 0.1f, 0.2f), Vec3(1, 0, 0), 2};
    beams[3] = BeamLine{Vec3(1, 0.1f, 0.21f), Vec3(-1, 0, 0), 2};
    std::vector<Ray> rays;
    for (int k = 0; k < 200; ++k)
        rays.push_back(Ray(random_point(rng), warp::square_to_uniform_sphere(rng.next_2d()), 0.0f,
                           0.2f + 3.0f * rng.next_1d()));
    rays.push_back(Ray(Vec3(-2.5f, 0.1f, 0.2f), Vec3(1, 0, 0), 0.0f, 5.0f));  // along an axis
    Aabb bounds;
    bounds.expand(Vec3(-6.0f));
    bounds.expand(Vec3(6.0f));
    for (float r : {0.01f, 0.05f, 0.2f})
        for (double cells_per_beam : {0.1, 1.0, 8.0}) {
            UniformBeamGrid grid;
            grid.build(beams, r, bounds, cells_per_beam);
            EXPECT_GE(check_queries(grid, beams, r, rays), 20) << r << " " << cells_per_beam;
        }
    // A 1e6-long beam and query in bounds that hold them.
    beams[1].length = 1e6f;
    rays.push_back(Ray(Vec3(0.3f, -2.5f, 0.2f), Vec3(0, 1, 0), 0.0f, 1e6f));
    bounds.expand(Vec3(-1.1e6f));
    bounds.expand(Vec3(1.1e6f));
    UniformBeamGrid grid;
    grid.build(beams, 0.05f, bounds);
    EXPECT_GE(check_queries(grid, beams, 0.05f, rays), 20);
}

TEST(BeamsAlongRay, ParallelZeroLengthAndHugeBeams) {
    BeamsAlongRay lookup;
    const std::vector<BeamLine> beams = {
        BeamLine{Vec3(0, 0.01f, 0), Vec3(1, 0, 0), 5},         // parallel to the query
        BeamLine{Vec3(0.5f, -0.01f, 0), Vec3(0, 1, 0), 0},     // length 0 across the query
        BeamLine{Vec3(2, -5e5f, 0.02f), Vec3(0, 1, 0), 1e6f},  // length 1e6 across it
        BeamLine{Vec3(3, 0.5f, 0.03f), Vec3(0, -1, 0), 1}};    // ordinary
    lookup.build(beams, 0.05f);
    std::map<uint32_t, BeamApproach> got;
    lookup.for_each_near(Ray(Vec3(0.0f), Vec3(1, 0, 0), 0.0f, 10.0f),
                         [&](uint32_t i, const BeamApproach& a) { got[i] = a; });
    EXPECT_EQ(got.count(0), 0u);  // parallel: no closest approach
    EXPECT_EQ(got.count(1), 0u);  // ends before it reaches the query line
    ASSERT_EQ(got.count(2), 1u);
    EXPECT_NEAR(got[2].t_ray, 2.0f, 1e-3f);
    EXPECT_NEAR(got[2].t_beam, 5e5f, 1.0f);
    EXPECT_NEAR(got[2].distance, 0.02f, 1e-3f);
    ASSERT_EQ(got.count(3), 1u);
    EXPECT_NEAR(got[3].t_beam, 0.5f, 1e-5f);
    EXPECT_NEAR(got[3].sin_theta, 1.0f, 1e-6f);
    // Rebuilt empty: nothing.
    const std::vector<BeamLine> none;
    lookup.build(none, 0.05f);
    int visits = 0;
    lookup.for_each_near(Ray(Vec3(0.0f), Vec3(1, 0, 0), 0.0f, 10.0f),
                         [&](uint32_t, const BeamApproach&) { ++visits; });
    EXPECT_EQ(visits, 0);
}

// bounds() lets upbp skip an eye segment's walk whose line misses it (Iteration::gather_reach):
// so every point where a query finds a beam (the query's closest approach) must lie inside it.
// Random beams and lines; planted, a box not grown by the radius leaves approaches outside.
template <typename Lookup>
void expect_approaches_inside_bounds(const Lookup& lookup, const std::vector<BeamLine>& beams,
                                     float r, Rng& rng) {
    const Aabb box = lookup.bounds();
    ASSERT_FALSE(box.empty());
    int found = 0;
    for (int k = 0; k < 400; ++k) {
        const Ray ray(random_point(rng) * 1.5f, warp::square_to_uniform_sphere(rng.next_2d()), 0.0f,
                      10.0f);
        lookup.for_each_near(ray, [&](uint32_t, const BeamApproach& a) {
            const Vec3 x = ray.at(a.t_ray);
            for (int axis = 0; axis < 3; ++axis) {
                EXPECT_GE(x[axis], box.lo[axis]);
                EXPECT_LE(x[axis], box.hi[axis]);
            }
            ++found;
        });
    }
    EXPECT_GE(found, 50);
}

TEST(BeamsAlongRay, BoundsHoldEveryApproachFound) {
    Rng rng(StreamKey{24, 0, 0, 0});
    std::vector<BeamLine> beams(300);
    for (BeamLine& b : beams)
        b = BeamLine{random_point(rng) * 0.5f, warp::square_to_uniform_sphere(rng.next_2d()),
                     rng.next_1d()};
    for (float r : {0.05f, 0.3f}) {
        BeamsAlongRay lookup;
        lookup.build(beams, r);
        expect_approaches_inside_bounds(lookup, beams, r, rng);
        Aabb bounds;
        bounds.expand(Vec3(-6.0f));
        bounds.expand(Vec3(6.0f));
        UniformBeamGrid grid;
        grid.build(beams, r, bounds);
        expect_approaches_inside_bounds(grid, beams, r, rng);
    }
    BeamsAlongRay empty;
    empty.build({}, 0.1f);
    EXPECT_TRUE(empty.bounds().empty());
}

}  // namespace
}  // namespace render
