// The up-front estimate of an algorithm's working memory per iteration
// (core/render/iteration_memory.h). Its calibration against measured peaks is
// scripts/memory-calibration (docs/results/reliability-probes.md, "Memory calibration"); these
// check what the estimate is made of.

#include "core/render/iteration_memory.h"

#include <gtest/gtest.h>

#include "core/base/memory_budget.h"
#include "core/integrators/bidirectional/record_bounds.h"
#include "core/render/algorithms.h"

namespace render {
namespace {
using namespace bidirectional;  // the record bounds

RenderSettings settings_for(const std::string& algorithm, int max_depth = -1, int rr_depth = 5) {
    RenderSettings s;
    s.algorithm = algorithm;
    s.max_depth = max_depth;
    s.rr_depth = rr_depth;
    return s;
}

TEST(IterationMemory, LightVerticesPerPathAreBoundedByTheDepthAndTheRoulette) {
    // Vertices 1 .. max_depth - 1 of a light subpath are stored.
    EXPECT_EQ(assumed_light_vertices_per_path(settings_for("vcm", 3)), 2u);
    EXPECT_EQ(assumed_light_vertices_per_path(settings_for("vcm", 1)), 0u);
    // Past rr_depth, Russian roulette's tail.
    EXPECT_EQ(assumed_light_vertices_per_path(settings_for("vcm", -1, 5)),
              5u + kRouletteTailVertices);
    EXPECT_EQ(assumed_light_vertices_per_path(settings_for("vcm", 65, 5)),
              5u + kRouletteTailVertices);
    EXPECT_EQ(assumed_light_vertices_per_path(settings_for("vcm", -1, 20)),
              20u + kRouletteTailVertices);
}

TEST(IterationMemory, StoredLightPathsGrowWithThePixelsOrTheLightPathCount) {
    const RenderSettings vcm = settings_for("vcm");
    const uint64_t small = estimate_iteration_memory(vcm, 256, 256, 2).bytes;
    const uint64_t large = estimate_iteration_memory(vcm, 512, 512, 2).bytes;
    // 3 x 65536 more light paths, each of up to 9 vertices of the stored vertex's bound plus
    // its 60-B merge index (with the 8-B arrival medium of a scene with media), and its 4-B end.
    EXPECT_EQ(large - small, 3u * 65536u * (9u * (kLightVertexBytesBound + 60u) + 4u));
    RenderSettings fixed = vcm;
    fixed.light_path_count = 1000;
    EXPECT_EQ(estimate_iteration_memory(fixed, 256, 256, 2).bytes,
              estimate_iteration_memory(fixed, 512, 512, 2).bytes);
    EXPECT_LT(estimate_iteration_memory(fixed, 512, 512, 2).bytes, small);
}

// J2 (bpt --joint-connections all) keeps a light path's rays in media (up to one per stored vertex
// and the emission ray, and the path's 4-B end) and its state of each stored vertex (a side
// array), also in the light pass's chunks; without J2 neither is charged (nor stored).
TEST(IterationMemory, JointSegmentConnectionsChargeTheirLightRaysAndVertexStates) {
    RenderSettings j1 = settings_for("bpt");
    j1.joint_connections = true;
    RenderSettings j2 = j1;
    j2.joint2_connections = true;
    const uint64_t paths = 256u * 256u;  // one light path per pixel
    const uint64_t vertices = assumed_light_vertices_per_path(j2);
    // 2 threads x 4 chunks in flight x 256 paths.
    const uint64_t chunk_paths = 2u * 4u * 256u;
    const uint64_t per_path =
        (vertices + 1) * kLightRayBytesBound + vertices * kJoint2VertexBytesBound;
    EXPECT_EQ(estimate_iteration_memory(j2, 256, 256, 2).bytes -
                  estimate_iteration_memory(j1, 256, 256, 2).bytes,
              paths * (per_path + 4) + chunk_paths * per_path);
    EXPECT_NE(estimate_iteration_memory(j2, 256, 256, 2).what.find("J2's light rays"),
              std::string::npos);
    EXPECT_EQ(estimate_iteration_memory(j1, 256, 256, 2).what.find("J2's"), std::string::npos);
    RenderSettings plain = settings_for("bpt");
    plain.joint2_connections = true;  // without joint_connections J2 does not run
    EXPECT_EQ(estimate_iteration_memory(plain, 256, 256, 2).bytes,
              estimate_iteration_memory(settings_for("bpt"), 256, 256, 2).bytes);
}

TEST(IterationMemory, EachAlgorithmChargesWhatItStores) {
    const uint64_t w = 512, h = 512;
    const uint64_t pt = estimate_iteration_memory(settings_for("pt"), w, h, 2).bytes;
    // Path tracing keeps nothing per pixel besides the film (charged apart): its threads only.
    EXPECT_EQ(pt, 2u << 20);
    EXPECT_EQ(estimate_iteration_memory(settings_for("volpt"), w, h, 2).bytes, pt);
    EXPECT_EQ(estimate_iteration_memory(settings_for("lt"), w, h, 2).bytes, pt);
    // Connections store light vertices; merges add their grids; upbp its beams.
    const uint64_t bpt = estimate_iteration_memory(settings_for("bpt"), w, h, 2).bytes;
    const uint64_t vcm = estimate_iteration_memory(settings_for("vcm"), w, h, 2).bytes;
    const uint64_t upbp = estimate_iteration_memory(settings_for("upbp"), w, h, 2).bytes;
    EXPECT_GT(bpt, 200u * w * h);
    EXPECT_GT(vcm, bpt);
    EXPECT_GT(upbp, vcm);
    EXPECT_EQ(estimate_iteration_memory(settings_for("path"), w, h, 2).bytes, pt);  // an alias
    // ic's importance records: a table entry per record and VPL.
    EXPECT_GT(estimate_iteration_memory(settings_for("ic"), w, h, 2).bytes,
              estimate_iteration_memory(settings_for("vpl"), w, h, 2).bytes + (w * h / 16) * 64);
}

// Every row of the algorithm table carries its estimate (Algorithm::iteration_memory, required
// by register_algorithm); an algorithm no row names has none, and the estimate says so instead
// of charging only the threads (a worker's memory refusal relies on the estimate).
TEST(IterationMemory, EveryAlgorithmOfTheTableIsEstimatedByItsRow) {
    for (const Algorithm& a : algorithms()) {
        const IterationMemoryEstimate e =
            estimate_iteration_memory(settings_for(a.name), 64, 64, 2);
        EXPECT_GE(e.bytes, 2u << 20) << a.name;
        EXPECT_EQ(e.what.rfind(a.name + "'s working memory", 0), 0u) << e.what;
    }
    EXPECT_THROW(estimate_iteration_memory(settings_for("no_such_algorithm"), 64, 64, 2),
                 std::invalid_argument);
}

// Short photon beams may replay their sampling walk (a chromatic grid), whose state lives in a
// side array beside the beams (one BeamReplay per beam); long beams never replay, and without
// photon beams there is nothing to replay.
TEST(IterationMemory, ShortPhotonBeamsChargeTheirReplayStates) {
    const RenderSettings short_beams = settings_for("upbp");
    ASSERT_TRUE(short_beams.photon_beams && short_beams.short_photon_beams);
    RenderSettings long_beams = short_beams;
    long_beams.short_photon_beams = false;
    RenderSettings no_beams = short_beams;
    no_beams.photon_beams = false;
    const uint64_t paths = 256u * 256u;
    const uint64_t vertices = assumed_light_vertices_per_path(short_beams);
    EXPECT_EQ(estimate_iteration_memory(short_beams, 256, 256, 2).bytes -
                  estimate_iteration_memory(long_beams, 256, 256, 2).bytes,
              paths * vertices * kBeamReplayBytesBound);
    EXPECT_EQ(estimate_iteration_memory(no_beams, 256, 256, 2).bytes,
              estimate_iteration_memory(long_beams, 256, 256, 2).bytes);
}

TEST(IterationMemory, TheMessageNamesTheAlgorithmTheEstimateAndWhatLowersIt) {
    const IterationMemoryEstimate e = estimate_iteration_memory(settings_for("vcm", 10), 64, 64, 1);
    EXPECT_NE(e.what.find("vcm's working memory per iteration (estimated " + format_bytes(e.bytes)),
              std::string::npos)
        << e.what;
    EXPECT_NE(e.what.find("4096 light paths x up to 9 stored vertices x " +
                          std::to_string(kLightVertexBytesBound + 60) + " B"),
              std::string::npos)
        << e.what;
    EXPECT_NE(e.what.find("--light-paths"), std::string::npos) << e.what;
    SceneMemoryBudget budget(e.bytes - 1, "test --max-memory");
    try {
        budget.charge(e.bytes, e.what);
        FAIL() << "charged past the limit";
    } catch (const MemoryLimitExceeded& error) {
        EXPECT_NE(std::string(error.what()).find("more than the"), std::string::npos);
    }
}

TEST(IterationMemory, HugeSettingsSaturateInsteadOfWrapping) {
    RenderSettings s = settings_for("vcm");
    s.light_path_count = UINT64_MAX / 2;
    EXPECT_EQ(estimate_iteration_memory(s, 65536, 65536, 1).bytes, UINT64_MAX);
}

}  // namespace
}  // namespace render
