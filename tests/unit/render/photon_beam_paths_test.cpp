// upbp --photon-beam-paths: photon beams from the first K of an iteration's N light paths
// (docs/design/media.md, "Photon beams", and docs/reference/algorithms.md). The plan counts K in
// the beams' normalisation and MIS constant and N everywhere else; the iteration contract holds
// with K < N. That the image stays right with K < N is checked where the other estimators are:
// the photon-beam furnace (integrators/volpt_test.cpp, MediumFurnace PhotonBeams) and the
// volumetric caustic (render/convergence_test.cpp, UpbpMatchesBptOnTheVolumetricCaustic).

#include <gtest/gtest.h>

#include <string>

#include "core/integrators/bidirectional/iteration_plan.h"
#include "core/math/constants.h"
#include "core/render/render_iterations.h"
#include "core/render/render_options.h"
#include "core/scene/loader/scene_loader.h"
#include "core/scene/scene.h"
#include "tests/support/iteration_contract.h"

namespace render {
namespace {

using bidirectional::IterationPlan;
using bidirectional::plan_iteration;

std::unique_ptr<Scene> isosph(int size) {
    return load_scene(std::string(RENDER_SOURCE_DIR) + "/scenes/smallupbp/isosph.xml",
                      {{"resx", std::to_string(size)}, {"resy", std::to_string(size)}});
}

BidirectionalConfig upbp_config(double photon_beam_paths, double query_beam_paths = 1) {
    BidirectionalConfig c;
    c.algorithm = BidirectionalAlgorithm::Upbp;
    c.merging.radius_factor = 0.01;
    c.upbp.query_beams = true;
    c.upbp.photon_beams = true;
    c.upbp.photon_beam_paths = photon_beam_paths;
    c.upbp.query_beam_paths = query_beam_paths;
    return c;
}

// 32 x 32 pixels: N = 1024 light paths. A quarter: K = 256; the beam normalisation and eta_1 K
// scale by exactly N / K, every other constant of the plan is unchanged.
TEST(PhotonBeamPaths, PlanCountsTheBeamPathsInTheBeamTermsOnly) {
    auto scene = isosph(32);
    const IterationPlan all = plan_iteration(upbp_config(1.0), *scene, 3);
    const IterationPlan quarter = plan_iteration(upbp_config(0.25), *scene, 3);
    ASSERT_EQ(all.light_path_count, 1024u);
    EXPECT_EQ(all.photon_beam_path_count, 1024u);
    EXPECT_EQ(quarter.light_path_count, 1024u);
    EXPECT_EQ(quarter.photon_beam_path_count, 256u);
    EXPECT_EQ(quarter.photon_beam_radius, all.photon_beam_radius);
    const double r = all.photon_beam_radius;
    EXPECT_FLOAT_EQ(all.photon_beam_normalization, float(1.0 / (2.0 * r * 1024)));
    EXPECT_FLOAT_EQ(quarter.photon_beam_normalization, float(1.0 / (2.0 * r * 256)));
    EXPECT_DOUBLE_EQ(all.mis_techniques.photon_beam_eta, 0.5 * r * 1024);
    EXPECT_DOUBLE_EQ(quarter.mis_techniques.photon_beam_eta, 0.5 * r * 256);
    // The other techniques count every light path.
    EXPECT_EQ(quarter.vm_normalization, all.vm_normalization);
    EXPECT_EQ(quarter.vm_normalization_volume, all.vm_normalization_volume);
    EXPECT_EQ(quarter.beam_normalization, all.beam_normalization);
    EXPECT_EQ(quarter.mis_techniques.surface_eta, all.mis_techniques.surface_eta);
    EXPECT_EQ(quarter.mis_techniques.point_eta, all.mis_techniques.point_eta);
    EXPECT_EQ(quarter.mis_techniques.query_beam_eta, all.mis_techniques.query_beam_eta);
}

// K = ceil(F N), at least one path and at most N.
TEST(PhotonBeamPaths, CountIsTheCeilingOfTheFractionAndAtLeastOne) {
    auto scene = isosph(10);  // N = 100
    EXPECT_EQ(plan_iteration(upbp_config(0.333), *scene, 1).photon_beam_path_count, 34u);
    EXPECT_EQ(plan_iteration(upbp_config(1e-9), *scene, 1).photon_beam_path_count, 1u);
    EXPECT_EQ(plan_iteration(upbp_config(0.999999), *scene, 1).photon_beam_path_count, 100u);
}

// The iteration contract with beams from a fraction of the paths: splitting the range and the
// thread count change nothing, also with 8192 light paths (32 chunks of 256) and K = 820, a
// prefix that ends inside a chunk traced by either thread.
TEST(PhotonBeamPaths, IterationContractWithBeamsFromAFractionOfThePaths) {
    auto scene = isosph(24);
    RenderSettings settings = resolve_render_settings("upbp", {}, scene->settings);
    settings.seed = 1234;
    settings.radius_factor = 0.02;
    settings.photon_beam_paths = 0.3;
    ASSERT_NO_FATAL_FAILURE(testing::expect_split_ranges_add_up(*scene, settings, 1, 3, 5));
    testing::expect_thread_count_changes_nothing(*scene, settings, IterationRange{3, 5});
    RenderSettings many_chunks = settings;
    many_chunks.light_path_count = 8192;
    many_chunks.photon_beam_paths = 0.1;
    testing::expect_thread_count_changes_nothing(*scene, many_chunks, IterationRange{3, 4});
}

// --query-beam-paths: query beams gather the photon points of the first K paths; P-B2D's
// normalisation and MIS constant count K (pi r^2 K), every other constant is unchanged.
TEST(QueryBeamPaths, PlanCountsThePathsInTheQueryBeamTermsOnly) {
    auto scene = isosph(32);
    const IterationPlan all = plan_iteration(upbp_config(1.0), *scene, 3);
    const IterationPlan quarter = plan_iteration(upbp_config(1.0, 0.25), *scene, 3);
    EXPECT_EQ(all.query_beam_path_count, 1024u);
    EXPECT_EQ(quarter.query_beam_path_count, 256u);
    EXPECT_EQ(quarter.photon_beam_path_count, 1024u);
    const double r = all.beam_radius;
    EXPECT_FLOAT_EQ(all.beam_normalization, float(1.0 / (kPi * r * r * 1024)));
    EXPECT_FLOAT_EQ(quarter.beam_normalization, float(1.0 / (kPi * r * r * 256)));
    EXPECT_DOUBLE_EQ(quarter.mis_techniques.query_beam_eta, kPi * r * r * 256);
    EXPECT_EQ(quarter.vm_normalization_volume, all.vm_normalization_volume);
    EXPECT_EQ(quarter.photon_beam_normalization, all.photon_beam_normalization);
    EXPECT_EQ(quarter.mis_techniques.point_eta, all.mis_techniques.point_eta);
    EXPECT_EQ(quarter.mis_techniques.photon_beam_eta, all.mis_techniques.photon_beam_eta);
    EXPECT_EQ(plan_iteration(upbp_config(1.0, 1e-9), *isosph(10), 1).query_beam_path_count, 1u);
}

// The iteration contract with query beams over a prefix of the photons that ends inside a chunk
// (8192 light paths in chunks of 256, K = 820).
TEST(QueryBeamPaths, IterationContractWithPhotonsFromAFractionOfThePaths) {
    auto scene = isosph(24);
    RenderSettings settings = resolve_render_settings("upbp", {}, scene->settings);
    settings.seed = 1234;
    settings.radius_factor = 0.02;
    settings.query_beam_paths = 0.3;
    ASSERT_NO_FATAL_FAILURE(testing::expect_split_ranges_add_up(*scene, settings, 1, 3, 5));
    RenderSettings many_chunks = settings;
    many_chunks.light_path_count = 8192;
    many_chunks.query_beam_paths = 0.1;
    testing::expect_thread_count_changes_nothing(*scene, many_chunks, IterationRange{3, 4});
}

}  // namespace
}  // namespace render
