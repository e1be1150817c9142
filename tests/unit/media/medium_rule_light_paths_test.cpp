// Mitsuba's medium rule along light subpaths (docs/design/media.md, "Which medium a path is
// in"): where nested shapes' declarations disagree, a region is in one medium for paths crossing
// it one way and in another for paths crossing it the other way. The image is the camera's
// reading; the bidirectional family's light-subpath techniques must estimate the same integral.
//
// The scene: a camera looking along +z through two null spheres that name an absorbing medium
// as their interior only (the outer of radius 2 at the origin, the inner of radius 1 at
// z = -0.5), at a diffuse plane at z = 3 lit by a point light between the outer sphere and the
// plane. On the axis the camera's rays are in the medium from z = -2 to z = 0.5 (entering both
// spheres) and in vacuum after leaving the inner one; read from the plane toward the camera the
// rule would put the medium on [-1.5, 2] instead. Light tracing reaches the pixels only through
// that region, so it shows the difference in full (it did before light subpaths read the rule
// as camera paths do); bpt and vcm show it by the light subpaths' MIS share. Each algorithm's
// image mean is compared with volpt's over independent batches of iterations.

#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "core/render/render_iterations.h"
#include "core/scene/loader/scene_loader.h"
#include "core/scene/scene.h"
#include "tests/support/statistics.h"

namespace render {
namespace {

const std::string kInteriorM1 = R"(<ref name="interior" id="m1"/>)";
const std::string kBothM1 = R"(<ref name="interior" id="m1"/><ref name="exterior" id="m1"/>)";

// `outer`, `inner`: the media references of each sphere; `inner_first`: the declaration order.
std::string light_subpath_scene(const std::string& outer, const std::string& inner,
                                bool inner_first) {
    const auto sphere = [](const char* radius, const char* z, const std::string& media) {
        return std::string(R"(<shape type="sphere"><float name="radius" value=")") + radius +
               R"("/><point name="center" x="0" y="0" z=")" + z + R"("/><bsdf type="null"/>)" +
               media + "</shape>\n";
    };
    const std::string spheres = inner_first ? sphere("1", "-0.5", inner) + sphere("2", "0", outer)
                                            : sphere("2", "0", outer) + sphere("1", "-0.5", inner);
    return R"(<scene version="3.0.0">
  <medium type="homogeneous" id="m1"><rgb name="sigma_t" value="0.7"/><float name="albedo" value="0"/></medium>
  <sensor type="perspective">
    <float name="fov" value="30"/>
    <transform name="to_world"><lookat origin="0, 0, -5" target="0, 0, 0" up="0, 1, 0"/></transform>
    <film type="hdrfilm"><integer name="width" value="12"/><integer name="height" value="12"/></film>
  </sensor>
  <emitter type="point"><point name="position" x="0" y="0" z="2.4"/><rgb name="intensity" value="1"/></emitter>
  <shape type="rectangle">
    <transform name="to_world"><scale value="4"/><rotate y="1" angle="180"/><translate z="3"/></transform>
    <bsdf type="diffuse"><rgb name="reflectance" value="0.5"/></bsdf>
  </shape>
  )" + spheres +
           "</scene>";
}

// The image mean (red channel) over `batches` independent blocks of `per_batch` iterations.
testing::MeanEstimate image_mean(const Scene& scene, const char* algorithm, int batches,
                                 uint64_t per_batch) {
    RenderSettings settings;
    settings.algorithm = algorithm;
    settings.seed = 11;
    std::vector<double> means;
    for (int b = 0; b < batches; ++b) {
        const uint64_t first = 1 + uint64_t(b) * per_batch;
        const IterationResult r =
            render_iterations(scene, settings, 0, IterationRange{first, first + per_batch});
        double sum = 0;
        for (size_t i = 0; i < r.sum.pixel_count(); ++i) sum += r.sum.channel(i, 0);
        means.push_back(sum / double(r.sum.pixel_count()) / double(r.count));
    }
    return testing::batch_means(means);
}

struct Case {
    const char* name;
    std::string outer, inner;
    bool inner_first;
};

// Tolerance: 5 combined standard errors of the two batch means (a false failure about once in
// 3 million runs per comparison). Before light subpaths read the rule as camera paths do, light
// tracing's mean on the disagreeing cases was about exp(-0.7) of volpt's on the pixels that see
// the plane through the spheres: tens of standard errors off.
TEST(MediumRuleLightSubpaths, EveryAlgorithmEstimatesTheCamerasIntegral) {
    const Case cases[] = {
        {"interiors only", kInteriorM1, kInteriorM1, false},
        {"interiors only, inner sphere declared first", kInteriorM1, kInteriorM1, true},
        // Declarations that agree: both readings give the same media (a control).
        {"inner names its exterior", kInteriorM1, kBothM1, false},
    };
    for (const Case& c : cases) {
        SCOPED_TRACE(c.name);
        auto scene =
            load_scene_from_string(light_subpath_scene(c.outer, c.inner, c.inner_first), ".");
        const testing::MeanEstimate reference = image_mean(*scene, "volpt", 8, 32);
        ASSERT_GT(reference.mean, 0.0);
        for (const char* algorithm : {"lt", "bpt", "vcm"}) {
            SCOPED_TRACE(algorithm);
            const testing::MeanEstimate m = image_mean(*scene, algorithm, 8, 32);
            const double se = std::hypot(m.standard_error, reference.standard_error);
            EXPECT_NEAR(m.mean, reference.mean, 5 * se)
                << "volpt " << reference.mean << " +- " << reference.standard_error;
        }
    }
}

}  // namespace
}  // namespace render
