// Hard cases for every algorithm (pt, lt, bpt, ppm, bpm, vcm): a vanishing merging radius,
// extreme scene scales, a light lying on a surface, emitters seen from behind, grazing
// connections, a degenerate triangle in a mesh light and an envmap with one extreme texel.
//
// Every image must stay finite (no dropped sample, every accumulated value finite). Where a
// correct value exists it is checked: against an analytic value, against the same scene at
// scale 1 with the same seed, or against another algorithm. Statistical comparisons use
// k = 5 combined standard errors; each standard error comes from the spread of the
// per-iteration means (iterations are independent: every random number is keyed by the
// iteration), i.e. the odd/even estimate generalised to n groups. Seeds are fixed, so every
// result is deterministic.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <unistd.h>

#include "core/image/exr_io.h"
#include "core/image/image.h"
#include "core/render/render_iterations.h"
#include "core/scene/loader/scene_loader.h"
#include "core/shapes/triangle_mesh.h"
#include "tests/support/statistics.h"
#include "tests/support/test_scenes.h"

namespace render {
namespace {

const std::vector<std::string> kAlgorithms = {"pt", "lt", "bpt", "ppm", "bpm", "vcm"};

// Statistical tolerance of every comparison, in combined standard errors.
constexpr double kSigmas = 5.0;

// A rectangle of pixels [x0, x1) x [y0, y1).
struct Region {
    std::string name;
    int x0, y0, x1, y1;
};

// The whole image and its four quadrants: the quadrants catch errors that a global mean
// would average away (a misplaced or missing light contribution).
std::vector<Region> image_and_quadrants(int width, int height) {
    int hx = width / 2, hy = height / 2;
    return {{"image", 0, 0, width, height},
            {"top-left", 0, 0, hx, hy},
            {"top-right", hx, 0, width, hy},
            {"bottom-left", 0, hy, hx, height},
            {"bottom-right", hx, hy, width, height}};
}

struct RenderSummary {
    std::string algorithm;
    int width = 0, height = 0;
    uint64_t iterations = 0;
    RenderStats stats;
    bool all_finite = true;
    std::vector<double> sum;  // 3 values per pixel: the sum over all iterations
    std::vector<Region> regions;
    // region_means[r][i]: mean of (R+G+B)/3 over region r in iteration i.
    std::vector<std::vector<double>> region_means;

    double pixel(int x, int y, int c) const {
        return sum[3 * (size_t(y) * width + x) + c] / double(iterations);
    }
    double mean(size_t r) const { return testing::batch_means(region_means[r]).mean; }
    // Standard error of mean(r) from the spread of the independent per-iteration means.
    double standard_error(size_t r) const {
        return testing::batch_means(region_means[r]).standard_error;
    }
    double total() const {
        double t = 0;
        for (double v : sum) t += v;
        return t;
    }
};

// Renders iterations 1..n one at a time (the iteration contract makes this identical to one
// call over [1, n+1)) to get independent per-iteration region means.
RenderSummary render_summary(const Scene& scene, const RenderSettings& settings,
                             uint64_t iterations) {
    RenderSummary out;
    out.algorithm = settings.algorithm;
    out.width = scene.camera().width();
    out.height = scene.camera().height();
    out.iterations = iterations;
    out.sum.assign(size_t(out.width) * out.height * 3, 0.0);
    out.regions = image_and_quadrants(out.width, out.height);
    out.region_means.assign(out.regions.size(), {});
    for (uint64_t i = 1; i <= iterations; ++i) {
        IterationResult r = render_iterations(scene, settings, 0, IterationRange{i, i + 1});
        out.stats += r.stats;
        const std::vector<double>& v = r.sum.values();
        for (size_t k = 0; k < v.size(); ++k) {
            if (!std::isfinite(v[k])) out.all_finite = false;
            out.sum[k] += v[k];
        }
        for (size_t g = 0; g < out.regions.size(); ++g) {
            const Region& reg = out.regions[g];
            double s = 0;
            for (int y = reg.y0; y < reg.y1; ++y)
                for (int x = reg.x0; x < reg.x1; ++x)
                    for (int c = 0; c < 3; ++c) s += v[3 * (size_t(y) * out.width + x) + c];
            out.region_means[g].push_back(s / (3.0 * (reg.x1 - reg.x0) * (reg.y1 - reg.y0)));
        }
    }
    return out;
}

// References (the pt image of a scene, ...) are rendered once per process and shared by the
// parameterised instances.
const RenderSummary& cached(const std::string& key, const std::function<RenderSummary()>& make) {
    static std::map<std::string, std::unique_ptr<RenderSummary>> cache;
    auto it = cache.find(key);
    if (it == cache.end()) it = cache.emplace(key, std::make_unique<RenderSummary>(make())).first;
    return *it->second;
}

void expect_finite(const RenderSummary& s) {
    EXPECT_EQ(s.stats.non_finite, 0u) << s.algorithm << ": dropped non-finite samples";
    EXPECT_TRUE(s.all_finite) << s.algorithm << ": a non-finite value reached the image";
    EXPECT_GT(s.stats.samples, 0u);
}

// Every region mean of `test` agrees with `reference` within kSigmas combined standard errors,
// plus `relative_bias` x the reference mean where a known (consistent-estimator) bias is
// allowed. The whole-image comparison must also be meaningful: its combined standard error
// below `max_relative_error` of the mean (otherwise a broken but noisy estimator would pass).
void expect_agreement(const RenderSummary& test, const RenderSummary& reference,
                      double relative_bias = 0.0, double max_relative_error = 0.05) {
    ASSERT_EQ(test.regions.size(), reference.regions.size());
    for (size_t r = 0; r < test.regions.size(); ++r) {
        const double a = test.mean(r), b = reference.mean(r);
        const double se = std::hypot(test.standard_error(r), reference.standard_error(r));
        EXPECT_LE(std::abs(a - b), kSigmas * se + relative_bias * std::abs(b))
            << test.algorithm << " vs " << reference.algorithm << ", " << test.regions[r].name
            << ": " << a << " vs " << b << " (combined SE " << se << ", "
            << (se > 0 ? std::abs(a - b) / se : 0.0) << " SE apart)";
        if (r == 0) {
            EXPECT_GT(b, 0.0) << "the reference image is black";
            EXPECT_LT(se, max_relative_error * b)
                << test.algorithm << ": comparison too noisy to mean anything";
        }
    }
}

std::string algorithm_name(const ::testing::TestParamInfo<std::string>& info) {
    return info.param;
}

class HardCase : public ::testing::TestWithParam<std::string> {
  protected:
    RenderSettings settings(uint64_t seed) const {
        RenderSettings s;
        s.algorithm = GetParam();
        s.seed = seed;
        return s;
    }
    bool merging_only() const { return GetParam() == "ppm" || GetParam() == "bpm"; }
    // Settings for comparisons: PPM and BPM estimate everything beyond the first bounce from
    // photon density, which is far noisier than connections at equal cost; they get 2 light
    // paths per pixel and twice the iterations so that 5 standard errors stay small.
    RenderSettings comparison_settings(uint64_t seed, int width, int height) const {
        RenderSettings s = settings(seed);
        if (merging_only()) s.light_path_count = 2 * uint64_t(width) * uint64_t(height);
        return s;
    }
    uint64_t comparison_iterations(uint64_t base) const { return merging_only() ? 2 * base : base; }
    // Known, consistent bias of density estimation (PPM, BPM: the merging radius blurs the
    // radiance over r = 0.003 x the scene radius, shrinking as i^-1/8; it darkens a band of
    // width r along edges and silhouettes): 2 % of the reference mean is allowed for them.
    double allowed_bias() const { return merging_only() ? 0.02 : 0.0; }
};

// A temporary directory for the files a test writes (removed at the end of the test).
class TempDir {
  public:
    explicit TempDir(const std::string& name) {
        path_ = std::filesystem::temp_directory_path() /
                ("hard_cases_test_" + name + "_" + std::to_string(::getpid()));
        std::filesystem::create_directories(path_);
    }
    ~TempDir() {
        std::error_code ec;
        std::filesystem::remove_all(path_, ec);
    }
    const std::filesystem::path& path() const { return path_; }

  private:
    std::filesystem::path path_;
};

// --- 1. merging radius 1e-7 x scene size ------------------------------------------------------

// radius_factor 1e-7: eta_VCM = pi r^2 N is ~1e-10, so the merging normalisation 1/eta and the
// MIS factor (1/eta)^2 ~ 1e20 are extreme but must stay finite. Merges then carry almost no
// weight in VCM, which becomes BPT: with the same seed it traces the same subpaths, and it must
// agree with BPT within 5 combined standard errors (per-iteration spread, 32 iterations). PPM
// and BPM: finiteness only (with nearly no merges their image is the directly visible light
// plus rare, enormous merges: unbiased but with no usable variance).
TEST_P(HardCase, TinyMergingRadius) {
    auto scene = load_scene_from_string(testing::scaled_box_scene(), ".");
    RenderSettings s = settings(101);
    s.radius_factor = 1e-7;
    const RenderSummary result = render_summary(*scene, s, 32);
    expect_finite(result);
    EXPECT_GT(result.total(), 0.0);
    if (GetParam() == "vcm") {
        const RenderSummary& bpt = cached("tiny-radius/bpt", [&] {
            RenderSettings b = s;
            b.algorithm = "bpt";
            return render_summary(*scene, b, 32);
        });
        expect_agreement(result, bpt);
        // Stronger, deterministic: VCM and BPT draw the same random numbers here, and VCM's
        // extra terms (merges, and eta^2 ~ 1e-20 in the connection weights) are negligible, so
        // the totals must agree to 1e-4 relative (observed: ~1e-7).
        EXPECT_NEAR(result.total() / bpt.total(), 1.0, 1e-4);
    }
}

// --- 2. scene scaled by 1e-3 and 1e4 ----------------------------------------------------------

// Radiance does not depend on scale and the merging radius is a fraction of the scene size, so
// with the same seed every algorithm draws the same random numbers and traces the same paths;
// only ray spawning and float rounding differ. Tolerance (deterministic, not statistical, the
// same as render_test's path-tracing check): the image totals agree to 0.5 % and at most 2 % of
// the values differ by more than 1e-3 relative (a path grazing an edge may take the other side
// at another float scale, and a light vertex near the merging radius may fall in or out).
// Observed: totals agree to ~1e-8, no value differs.
TEST_P(HardCase, SceneScaledBy1e3And1e4) {
    const uint64_t iterations = 8;
    const RenderSummary& unit = cached("scale-1/" + GetParam(), [&] {
        auto scene = load_scene_from_string(testing::scaled_box_scene(), ".", {{"s", "1"}});
        return render_summary(*scene, settings(3), iterations);
    });
    expect_finite(unit);
    ASSERT_GT(unit.total(), 0.0);
    for (const std::string scale : {"1e-3", "1e4"}) {
        SCOPED_TRACE("scale " + scale);
        auto scene = load_scene_from_string(testing::scaled_box_scene(), ".", {{"s", scale}});
        const RenderSummary scaled = render_summary(*scene, settings(3), iterations);
        expect_finite(scaled);
        size_t differing = 0;
        for (size_t i = 0; i < unit.sum.size(); ++i) {
            double a = unit.sum[i], b = scaled.sum[i];
            if (std::abs(a - b) > 1e-3 * std::max(std::abs(a), 1e-3)) ++differing;
        }
        EXPECT_NEAR(scaled.total() / unit.total(), 1.0, 5e-3) << GetParam();
        EXPECT_LT(double(differing) / double(unit.sum.size()), 0.02) << GetParam();
    }
}

// --- 3. a light lying on a surface ----------------------------------------------------------

// An area-light rectangle (no BSDF: black) lying exactly in the plane of a diffuse floor
// (coplanar, overlapping, both facing up), lighting a sphere and a back wall above it. Light
// rays start on the floor plane and must not be captured by it; next-event estimation from the
// floor toward the light is exactly grazing (cos 0). Where the two overlap, which surface a ray
// reports is decided by float rounding (z-fighting: with max_depth 1, camera rays see the
// emitter in only ~20 % of the samples of its interior pixels); camera rays make that decision
// identically for every algorithm, and the comparison shows that light paths and next-event
// estimation do not disagree with it measurably. Every algorithm must agree with pt within
// 5 combined standard errors (per-iteration spread) on the image and its quadrants (PPM and
// BPM: plus their 2 % merging-bias allowance).
std::string light_on_floor_scene() {
    return R"(<scene version="3.0.0">
  <sensor type="perspective">
    <float name="fov" value="55"/>
    <transform name="to_world"><lookat origin="0, 2, 4" target="0, 0.5, 0" up="0, 1, 0"/></transform>
    <film type="hdrfilm"><integer name="width" value="32"/><integer name="height" value="32"/></film>
  </sensor>
  <bsdf type="diffuse" id="white"><rgb name="reflectance" value="0.6"/></bsdf>
  <shape type="rectangle">
    <transform name="to_world"><rotate x="1" angle="-90"/><scale value="3"/></transform>
    <ref id="white"/>
  </shape>
  <shape type="rectangle">
    <transform name="to_world"><scale value="3"/><translate z="-1.5"/></transform>
    <ref id="white"/>
  </shape>
  <shape type="sphere">
    <point name="center" x="0.4" y="1.1" z="0"/>
    <float name="radius" value="0.5"/>
    <ref id="white"/>
  </shape>
  <shape type="rectangle">
    <transform name="to_world"><rotate x="1" angle="-90"/><scale value="0.4"/><translate x="-0.3" z="0.3"/></transform>
    <emitter type="area"><rgb name="radiance" value="8"/></emitter>
  </shape>
</scene>)";
}

TEST_P(HardCase, LightLyingOnAFloor) {
    auto scene = load_scene_from_string(light_on_floor_scene(), ".");
    const int w = scene->camera().width(), h = scene->camera().height();
    const RenderSummary result =
        render_summary(*scene, comparison_settings(5, w, h), comparison_iterations(64));
    expect_finite(result);
    if (GetParam() == "pt") return;
    const RenderSummary& pt = cached("light-on-floor/pt", [&] {
        RenderSettings p = settings(6);
        p.algorithm = "pt";
        return render_summary(*scene, p, 256);
    });
    expect_agreement(result, pt, allowed_bias());
}

// --- 4. an emitter seen from behind ------------------------------------------------------------

// A one-sided area light (no BSDF: black) facing away from the camera toward a diffuse wall.
// Pixels that see only the back of the light receive no emission and, the light being black,
// nothing else: they must be exactly 0 in every algorithm. The wall around it must be lit
// (the light does emit), and with the light flipped the same pixels must be exactly its
// radiance (the region is right and only emission reaches it).
std::string back_of_light_scene() {
    return R"(<scene version="3.0.0">
  <default name="flip" value="false"/>
  <sensor type="perspective">
    <float name="fov" value="40"/>
    <transform name="to_world"><lookat origin="0, 0, 5" target="0, 0, 0" up="0, 1, 0"/></transform>
    <film type="hdrfilm"><integer name="width" value="24"/><integer name="height" value="24"/></film>
  </sensor>
  <shape type="rectangle">
    <transform name="to_world"><scale value="4"/><translate z="-2"/></transform>
    <bsdf type="diffuse"><rgb name="reflectance" value="0.7"/></bsdf>
  </shape>
  <shape type="rectangle">
    <transform name="to_world"><rotate y="1" angle="180"/></transform>
    <boolean name="flip_normals" value="$flip"/>
    <emitter type="area"><rgb name="radiance" value="4"/></emitter>
  </shape>
</scene>)";
}

TEST_P(HardCase, EmitterSeenFromBehindIsBlack) {
    auto scene = load_scene_from_string(back_of_light_scene(), ".");
    // Pixels entirely inside the projection of the light [-1, 1]^2 at z = 0 (parallel to the
    // image plane, so its projection is an axis-aligned raster rectangle), one pixel of margin.
    const PerspectiveCamera& camera = scene->camera();
    float lo_x = 1e30f, hi_x = -1e30f, lo_y = 1e30f, hi_y = -1e30f;
    for (float cx : {-1.0f, 1.0f})
        for (float cy : {-1.0f, 1.0f}) {
            std::optional<Vec2> p = camera.raster_position(Vec3(cx, cy, 0));
            ASSERT_TRUE(p.has_value());
            lo_x = std::min(lo_x, p->x), hi_x = std::max(hi_x, p->x);
            lo_y = std::min(lo_y, p->y), hi_y = std::max(hi_y, p->y);
        }
    const int x0 = int(std::ceil(lo_x)) + 1, x1 = int(std::floor(hi_x)) - 1;
    const int y0 = int(std::ceil(lo_y)) + 1, y1 = int(std::floor(hi_y)) - 1;
    ASSERT_GE(x1 - x0, 4);
    ASSERT_GE(y1 - y0, 4);

    const RenderSummary back = render_summary(*scene, settings(7), 16);
    expect_finite(back);
    double outside = 0;
    for (int y = 0; y < back.height; ++y)
        for (int x = 0; x < back.width; ++x)
            for (int c = 0; c < 3; ++c) {
                if (x >= x0 && x < x1 && y >= y0 && y < y1)
                    ASSERT_EQ(back.pixel(x, y, c), 0.0)
                        << GetParam() << " pixel " << x << ", " << y;
                else
                    outside += back.pixel(x, y, c);
            }
    EXPECT_GT(outside, 0.0) << "the wall around the light must be lit";

    auto flipped = load_scene_from_string(back_of_light_scene(), ".", {{"flip", "true"}});
    const RenderSummary front = render_summary(*flipped, settings(7), 16);
    expect_finite(front);
    for (int y = y0; y < y1; ++y)
        for (int x = x0; x < x1; ++x)
            for (int c = 0; c < 3; ++c)
                ASSERT_NEAR(front.pixel(x, y, c), 4.0, 1e-6)
                    << GetParam() << " pixel " << x << ", " << y;
}

// --- 5. grazing connections ------------------------------------------------------------------

// Planes that every technique meets edge-on: an area light lying in the plane of a wall
// (beside it, so every wall vertex sees it at cos 0), a point light exactly in the plane of the
// floor (every floor vertex connects to it at cos 0, and half its rays start exactly on the
// floor), a directional light travelling parallel to the floor, and coplanar connections
// between two floor (or two wall) vertices, where |cos| is ~1e-8 from rounding alone.
// `eye_y`/`target_y` place the camera.
std::string grazing_scene() {
    return R"(<scene version="3.0.0">
  <default name="eye_y" value="0.6"/>
  <default name="target_y" value="0.3"/>
  <sensor type="perspective">
    <float name="fov" value="60"/>
    <transform name="to_world"><lookat origin="2.5, $eye_y, 3" target="-1, $target_y, -0.5" up="0, 1, 0"/></transform>
    <film type="hdrfilm"><integer name="width" value="32"/><integer name="height" value="32"/></film>
  </sensor>
  <bsdf type="twosided" id="white"><bsdf type="diffuse"><rgb name="reflectance" value="0.6"/></bsdf></bsdf>
  <shape type="rectangle">
    <transform name="to_world"><rotate x="1" angle="-90"/><scale value="6"/></transform>
    <ref id="white"/>
  </shape>
  <shape type="rectangle">
    <transform name="to_world"><rotate y="1" angle="90"/><scale x="1" y="2" z="2"/><translate x="-1" y="2" z="-2"/></transform>
    <ref id="white"/>
  </shape>
  <shape type="rectangle">
    <transform name="to_world"><rotate y="1" angle="90"/><scale value="0.5"/><translate x="-1" y="1" z="0.75"/></transform>
    <emitter type="area"><rgb name="radiance" value="6"/></emitter>
  </shape>
  <emitter type="point">
    <point name="position" x="0.5" y="0" z="-1"/>
    <rgb name="intensity" value="2"/>
  </emitter>
  <emitter type="directional">
    <vector name="direction" x="-1" y="0" z="0"/>
    <rgb name="irradiance" value="0.5"/>
  </emitter>
</scene>)";
}

// Seen from 0.6 above the floor: finite, and agreeing with pt within 5 combined SE.
TEST_P(HardCase, GrazingConnections) {
    auto scene = load_scene_from_string(grazing_scene(), ".");
    const int w = scene->camera().width(), h = scene->camera().height();
    const RenderSummary result =
        render_summary(*scene, comparison_settings(9, w, h), comparison_iterations(64));
    expect_finite(result);
    if (GetParam() == "pt") return;
    const RenderSummary& pt = cached("grazing/pt", [&] {
        RenderSettings p = settings(10);
        p.algorithm = "pt";
        return render_summary(*scene, p, 256);
    });
    expect_agreement(result, pt, allowed_bias());
}

// The camera 1e-6 above the floor looking along it (1e-7 of the scene radius, far below the
// ray-spawning offset): the floor near the horizon is seen at cosines down to 0, and light
// vertices on the floor connect to the camera at |cos| ~ 1e-6. Only finiteness is checked: the
// floor seen by the lower half of the image lies within a few millimetres of the camera, an area
// that light paths (LT, and the merges of PPM/BPM) essentially never reach in a few iterations,
// so their image there has a heavy-tailed error that no standard error estimate captures.
TEST_P(HardCase, CameraAlmostInTheFloorPlane) {
    auto scene =
        load_scene_from_string(grazing_scene(), ".", {{"eye_y", "1e-6"}, {"target_y", "1e-6"}});
    const RenderSummary result = render_summary(*scene, settings(15), 32);
    expect_finite(result);
    EXPECT_GT(result.total(), 0.0);
}

// --- 6. a zero-area triangle in a mesh light ----------------------------------------------------

// An OBJ quad light (facing down) with a third, degenerate triangle whose vertices are
// collinear and shared with the quad; no normals in the file, so smooth normals are computed
// from the faces, degenerate one included. Finite, and agreeing with pt within 5 combined SE.
const char* kDegenerateLightObj = R"(# quad light with a zero-area triangle
v -0.5 0 -0.5
v 0.5 0 -0.5
v 0.5 0 0.5
v -0.5 0 0.5
v 0 0 -0.5
f 1 2 3
f 1 3 4
f 1 5 2
)";

std::string degenerate_light_scene() {
    return R"(<scene version="3.0.0">
  <sensor type="perspective">
    <float name="fov" value="50"/>
    <transform name="to_world"><lookat origin="0, 1, 4" target="0, 0.8, 0" up="0, 1, 0"/></transform>
    <film type="hdrfilm"><integer name="width" value="32"/><integer name="height" value="32"/></film>
  </sensor>
  <bsdf type="diffuse" id="white"><rgb name="reflectance" value="0.6"/></bsdf>
  <shape type="rectangle">
    <transform name="to_world"><rotate x="1" angle="-90"/><scale value="2"/></transform>
    <ref id="white"/>
  </shape>
  <shape type="rectangle">
    <transform name="to_world"><scale value="2"/><translate y="1" z="-1"/></transform>
    <ref id="white"/>
  </shape>
  <shape type="sphere">
    <point name="center" x="-0.3" y="0.4" z="0"/>
    <float name="radius" value="0.4"/>
    <ref id="white"/>
  </shape>
  <shape type="obj">
    <string name="filename" value="degenerate_light.obj"/>
    <transform name="to_world"><translate y="1.9"/></transform>
    <emitter type="area"><rgb name="radiance" value="6"/></emitter>
  </shape>
</scene>)";
}

TEST_P(HardCase, ZeroAreaTriangleInMeshLight) {
    TempDir dir("degenerate");
    {
        std::ofstream obj(dir.path() / "degenerate_light.obj");
        obj << kDegenerateLightObj;
    }
    auto scene = load_scene_from_string(degenerate_light_scene(), dir.path());
    // The degenerate face is kept (3 triangles) and adds no area (the quad's area is 1).
    const auto* mesh = dynamic_cast<const TriangleMesh*>(scene->shapes().back().get());
    ASSERT_NE(mesh, nullptr);
    EXPECT_EQ(mesh->triangle_count(), 3u);
    EXPECT_NEAR(mesh->surface_area(), 1.0, 1e-6);
    const int w = scene->camera().width(), h = scene->camera().height();
    const RenderSummary result =
        render_summary(*scene, comparison_settings(11, w, h), comparison_iterations(64));
    expect_finite(result);
    if (GetParam() == "pt") return;
    const RenderSummary& pt = cached("degenerate/pt", [&] {
        RenderSettings p = settings(12);
        p.algorithm = "pt";
        return render_summary(*scene, p, 256);
    });
    expect_agreement(result, pt, allowed_bias());
}

// --- 7. an envmap with a single very bright texel ----------------------------------------------

// A 16 x 8 lat-long map, 0.1 everywhere except one texel of 1e6 (a small sun ~30 degrees above
// the horizon, off screen), over a diffuse floor with a sphere. Finite for every algorithm; the
// unbiased ones (lt, bpt, vcm) must agree with pt within 5 combined standard errors.
std::string envmap_scene() {
    return R"(<scene version="3.0.0">
  <sensor type="perspective">
    <float name="fov" value="50"/>
    <transform name="to_world"><lookat origin="0, 1.5, 4" target="0, 0.3, 0" up="0, 1, 0"/></transform>
    <film type="hdrfilm"><integer name="width" value="32"/><integer name="height" value="32"/></film>
  </sensor>
  <bsdf type="diffuse" id="white"><rgb name="reflectance" value="0.5"/></bsdf>
  <shape type="rectangle">
    <transform name="to_world"><rotate x="1" angle="-90"/><scale value="2"/></transform>
    <ref id="white"/>
  </shape>
  <shape type="sphere">
    <point name="center" x="0" y="0.5" z="0"/>
    <float name="radius" value="0.5"/>
    <ref id="white"/>
  </shape>
  <emitter type="envmap">
    <string name="filename" value="bright_texel.exr"/>
  </emitter>
</scene>)";
}

TEST_P(HardCase, EnvmapWithOneVeryBrightTexel) {
    TempDir dir("envmap");
    Image map(16, 8);
    for (size_t i = 0; i < map.pixel_count(); ++i) map.set(i, Rgb(0.1f));
    // Row 2 (polar angle 45..67.5 degrees), column 4 (azimuth toward +x): beside the camera.
    map.set(2 * 16 + 4, Rgb(1e6f));
    write_exr(dir.path() / "bright_texel.exr", map);
    auto scene = load_scene_from_string(envmap_scene(), dir.path());
    const int w = scene->camera().width(), h = scene->camera().height();
    // PPM and BPM: finiteness only. Each photon of the bright texel carries the sun's whole
    // power over the scene disk (~3e6), and an eye vertex finds one with probability ~1 %, so
    // their estimate is heavy-tailed: with 2 light paths per pixel the standard error is still
    // ~7 % of the mean after 128 iterations (~3 % after 1024), too coarse for a meaningful
    // comparison at unit-test cost.
    const RenderSummary result = merging_only()
                                     ? render_summary(*scene, settings(13), 64)
                                     : render_summary(*scene, comparison_settings(13, w, h), 64);
    expect_finite(result);
    EXPECT_GT(result.total(), 0.0);
    if (GetParam() == "pt" || merging_only()) return;
    const RenderSummary& pt = cached("envmap/pt", [&] {
        RenderSettings p = settings(14);
        p.algorithm = "pt";
        return render_summary(*scene, p, 256);
    });
    expect_agreement(result, pt, allowed_bias());
}

INSTANTIATE_TEST_SUITE_P(Algorithms, HardCase, ::testing::ValuesIn(kAlgorithms), algorithm_name);

}  // namespace
}  // namespace render
