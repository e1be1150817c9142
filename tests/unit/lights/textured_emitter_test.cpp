// Textured area lights: the radiance seen at a hit, the radiance of illuminate() and emit()
// samples and the power all follow the texture at the emitting point's uv; every shape's uv
// lookup from a point agrees with the uv its hits and its area samples report; a directly
// seen checkerboard emitter shows its two colours with every algorithm.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "core/base/error.h"
#include "core/lights/area_light.h"
#include "core/math/constants.h"
#include "core/render/render_iterations.h"
#include "core/sampling/rng.h"
#include "core/scene/loader/scene_loader.h"
#include "tests/support/algorithms.h"
#include "tests/support/statistics.h"

namespace render {
namespace {

#define EXPECT_CONTAINS(haystack, needle) \
    EXPECT_NE(std::string(haystack).find(needle), std::string::npos) << (haystack)

const Rgb kColor0(4.0f, 2.0f, 1.0f), kColor1(0.5f, 1.0f, 3.0f);

// A 2 x 2 rectangle at z = 0 facing +z (uv = ((x + 1) / 2, (y + 1) / 2)) emitting a
// checkerboard, seen from +z by a 32 x 32 camera with +y up that it fills.
std::string checker_emitter_scene() {
    return R"(<scene version="3.0.0">
  <sensor type="perspective">
    <float name="fov" value="30"/>
    <transform name="to_world"><lookat origin="0, 0, 3" target="0, 0, 0" up="0, 1, 0"/></transform>
    <film type="hdrfilm"><integer name="width" value="32"/><integer name="height" value="32"/></film>
  </sensor>
  <shape type="rectangle">
    <emitter type="area">
      <texture type="checkerboard" name="radiance">
        <rgb name="color0" value="4, 2, 1"/><rgb name="color1" value="0.5, 1, 3"/>
      </texture>
    </emitter>
  </shape>
</scene>)";
}

// Mitsuba's checkerboard at the rectangle's point (x, y).
Rgb checker_at(float x, float y) {
    const float u = 0.5f * (x + 1), v = 0.5f * (y + 1);
    return (u > 0.5f) == (v > 0.5f) ? kColor0 : kColor1;
}

TEST(TexturedAreaLight, RadianceFollowsTheTextureAtTheEmittingPoint) {
    auto scene = load_scene_from_string(checker_emitter_scene(), ".");
    ASSERT_EQ(scene->lights().size(), 1u);
    const Light& light = *scene->lights()[0];
    // Hits: the point's own square (a ray straight down at (x, y)).
    for (const Vec2 p :
         {Vec2(0.5f, 0.5f), Vec2(-0.5f, 0.5f), Vec2(-0.3f, -0.7f), Vec2(0.9f, -0.1f)}) {
        SurfaceInteraction si;
        const Ray ray(Vec3(p.x, p.y, 1), Vec3(0, 0, -1));
        ASSERT_TRUE(scene->intersect(ray, si));
        ASSERT_EQ(si.emitter, &light);
        EXPECT_EQ(light.radiance(si.p, si.geometric_normal, ray.direction).radiance,
                  checker_at(p.x, p.y));
    }
    // illuminate() and emit(): the sampled point's square, which the test finds from the point.
    Rng rng(StreamKey{3, 0, 7, 0});
    const Vec3 receiver(0.2f, -0.1f, 1.5f);
    int zero_area_misses = 0;
    for (int i = 0; i < 200; ++i) {
        LightIlluminateSample ls;
        if (!light.illuminate(receiver, rng.next_2d(), ls)) {
            ++zero_area_misses;
            continue;
        }
        const Vec3 q = receiver + ls.wi * ls.distance;
        // Points within 1e-4 of a square's edge could round either way.
        if (std::abs(q.x) < 1e-4f || std::abs(q.y) < 1e-4f) continue;
        EXPECT_EQ(ls.radiance, checker_at(q.x, q.y)) << q;
        LightEmitSample es;
        ASSERT_TRUE(light.emit(rng.next_2d(), rng.next_2d(), es));
        if (std::abs(es.origin.x) < 1e-4f || std::abs(es.origin.y) < 1e-4f) continue;
        const Rgb le = checker_at(es.origin.x, es.origin.y);
        for (int c = 0; c < 3; ++c)
            EXPECT_NEAR(es.energy[c], le[c] * es.cos_at_light, 1e-5f * le[c]) << es.origin;
    }
    EXPECT_EQ(zero_area_misses, 0);  // every point of the rectangle faces the receiver
    // Power: pi * area * the texture's mean, (color0 + color1) / 2.
    const Rgb power = light.power();
    for (int c = 0; c < 3; ++c)
        EXPECT_NEAR(power[c], kPi * 4.0f * 0.5f * (kColor0[c] + kColor1[c]), 1e-4f * power[c]);
}

// Every shape with a uv lookup finds, from a point, the uv its hit there reported, and its area
// samples report the uv of their point.
TEST(TexturedAreaLight, ShapesFindTheUvOfAPoint) {
    auto scene = load_scene_from_string(R"(<scene version="3.0.0">
      <sensor type="perspective"><float name="fov" value="45"/></sensor>
      <shape type="sphere"><point name="center" value="0, 0, 5"/>
        <transform name="to_world"><rotate x="1" y="1" angle="30"/></transform></shape>
      <shape type="disk"><transform name="to_world"><scale x="2" y="1"/><rotate y="1" angle="20"/>
        <translate x="5"/></transform></shape>
      <shape type="rectangle"><transform name="to_world"><scale x="1" y="3"/>
        <translate x="-5"/></transform></shape>
      <shape type="cube"><transform name="to_world"><translate y="5"/></transform></shape>
    </scene>)",
                                        ".");
    Rng rng(StreamKey{4, 0, 1, 0});
    for (const auto& shape : scene->shapes()) {
        SCOPED_TRACE(shape->to_string());
        ASSERT_TRUE(shape->has_uv_lookup());
        const Aabb box = shape->bounds();
        const Vec3 centre = (box.lo + box.hi) * 0.5f;
        int hits = 0;
        for (int i = 0; i < 300; ++i) {
            // Area samples: their uv is the uv at their point.
            const ShapeSample s = shape->sample_area(rng.next_2d());
            // 1e-4: positions are O(5), so float rounding of the point moves uv by ~1e-6.
            // Points within 1e-3 of uv's 0 or 1 are skipped: the sphere's and disk's phi = 0
            // seam, the poles and the disk's centre, a cube's edges (shared by two faces).
            auto inside = [](Vec2 uv) {
                return std::min({uv.x, uv.y, 1 - uv.x, 1 - uv.y}) > 1e-3f;
            };
            if (inside(s.uv)) {
                const Vec2 found = shape->uv_at(s.p);
                EXPECT_NEAR(found.x, s.uv.x, 1e-4f) << s.p;
                EXPECT_NEAR(found.y, s.uv.y, 1e-4f) << s.p;
            }
            // Hits: a ray from outside the bounds toward the sampled point.
            const Vec3 origin = centre + normalize(s.p - centre + s.n * 0.5f) * 20.0f;
            SurfaceInteraction si;
            if (!scene->intersect(Ray(origin, normalize(s.p - origin)), si, HitDetail::kWithUv) ||
                si.shape != shape.get())
                continue;
            ++hits;
            if (!inside(si.uv)) continue;
            const Vec2 at_hit = shape->uv_at(si.p);
            EXPECT_NEAR(at_hit.x, si.uv.x, 1e-4f) << si.p;
            EXPECT_NEAR(at_hit.y, si.uv.y, 1e-4f) << si.p;
        }
        EXPECT_GT(hits, 100);
    }
}

class TexturedEmitterSeen : public ::testing::TestWithParam<std::string> {};

// The emitter fills the image; its right half is world +x, its top world +y. Each algorithm
// must show color0 in the top-right and bottom-left quadrants and color1 elsewhere: eye paths
// see it through radiance(), light paths (lt, ppm, bpm) through emit().
TEST_P(TexturedEmitterSeen, ShowsBothColours) {
    auto scene = load_scene_from_string(checker_emitter_scene(), ".");
    RenderSettings settings = testing::algorithm_settings(GetParam());
    settings.seed = 17;
    struct Quadrant {
        const char* name;
        int x0, y0;
        Rgb expected;
    };
    const Quadrant quadrants[] = {{"top-right", 20, 4, kColor0},
                                  {"bottom-left", 4, 20, kColor0},
                                  {"top-left", 4, 4, kColor1},
                                  {"bottom-right", 20, 20, kColor1}};
    // Block means (8 x 8 pixels, 4 in from the seams) of independent iterations: their spread
    // gives the standard error, whatever the correlation between the pixels of one iteration.
    std::vector<std::vector<double>> means(4 * 3);
    for (uint64_t i = 1; i <= 24; ++i) {
        const IterationResult r = render_iterations(*scene, settings, 0, IterationRange{i, i + 1});
        ASSERT_EQ(r.stats.non_finite, 0u);
        for (int q = 0; q < 4; ++q)
            for (int c = 0; c < 3; ++c) {
                double sum = 0;
                for (int y = quadrants[q].y0; y < quadrants[q].y0 + 8; ++y)
                    for (int x = quadrants[q].x0; x < quadrants[q].x0 + 8; ++x)
                        sum += r.sum.channel(size_t(y) * 32 + size_t(x), c);
                means[size_t(q * 3 + c)].push_back(sum / 64);
            }
    }
    for (int q = 0; q < 4; ++q)
        for (int c = 0; c < 3; ++c) {
            const testing::MeanEstimate m = testing::batch_means(means[size_t(q * 3 + c)]);
            const double expected = quadrants[q].expected[c];
            // 5 standard errors (23 degrees of freedom): a false failure ~1e-4 per check; the
            // colours differ by at least 1 per channel, and the error must stay below 0.1 of it.
            EXPECT_NEAR(m.mean, expected, 5 * m.standard_error + 1e-6 * expected)
                << quadrants[q].name << " channel " << c << ", SE " << m.standard_error;
            EXPECT_LT(5 * m.standard_error, 0.1 * expected) << quadrants[q].name << " " << c;
        }
}

INSTANTIATE_TEST_SUITE_P(Algorithms, TexturedEmitterSeen,
                         ::testing::ValuesIn(testing::physically_based_algorithms()));

}  // namespace
}  // namespace render
