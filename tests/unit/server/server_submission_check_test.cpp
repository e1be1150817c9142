// Submission checking on its own (server/submission_check.h): the settings resolved from the
// scene, the film and iteration limits, an animation's frames and its validation budget, and
// the bundle's assets.

#include <gtest/gtest.h>

#include <fstream>
#include <map>
#include <string>

#include "core/render/job_limits.h"
#include "server/submission_check.h"
#include "tests/support/server_test_scene.h"
#include "tests/support/temp_dir.h"

using namespace render;
using namespace render::server;
namespace fs = std::filesystem;
namespace v1 = render::v1;

namespace {

// The server tests' scene with a sample_count of 7, the iterations a job takes by default.
std::string scene_with_seven_samples() {
    std::string scene = render::testing::kServerTestScene;
    const std::string sampler =
        R"(<sampler type="independent"><integer name="sample_count" value="7"/></sampler>)";
    scene.insert(scene.find("</sensor>"), sampler);
    return scene;
}

struct SubmissionCheckTest : ::testing::Test {
    fs::path dir;
    void SetUp() override {
        dir = render::testing::fresh_temp_dir(
            "server_submission_check_test",
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
        std::ofstream(dir / "scene.xml") << scene_with_seven_samples();
    }
    void TearDown() override { fs::remove_all(dir); }

    static v1::SubmitJobRequest request() {
        v1::SubmitJobRequest r;
        r.mutable_settings()->set_algorithm("pt");
        r.mutable_bundle()->set_scene_path("scene.xml");
        v1::BundleFile* f = r.mutable_bundle()->add_files();
        f->set_path("scene.xml");
        f->set_sha256("abc");
        f->set_size(12);
        return r;
    }
    static void add_frames(v1::SubmitJobRequest& r, std::initializer_list<const char*> values) {
        for (const char* value : values) (*r.add_frames()->mutable_defines())["r"] = value;
    }
};

}  // namespace

TEST_F(SubmissionCheckTest, ResolvesTheSettingsFromTheScene) {
    const SubmissionCheck check = check_submission(request(), dir, 120);
    ASSERT_TRUE(check.job) << check.rejection.status.error_message();
    const v1::RenderSettings& s = check.job->request.settings();
    EXPECT_EQ(s.algorithm(), "pt");
    EXPECT_EQ(s.iterations(), 7u);  // the scene's sample_count
    EXPECT_EQ(s.width(), 8u);
    EXPECT_EQ(s.height(), 6u);
    EXPECT_GT(s.options_size(), 0);  // the complete options pt reads
    EXPECT_EQ(check.job->frames, 1u);
}

TEST_F(SubmissionCheckTest, KeepsTheRequestsIterationsFilmAndTimeBudget) {
    v1::SubmitJobRequest r = request();
    r.mutable_settings()->set_iterations(3);
    r.mutable_settings()->set_width(16);
    r.mutable_settings()->set_height(4);
    SubmissionCheck check = check_submission(r, dir, 120);
    ASSERT_TRUE(check.job);
    EXPECT_EQ(check.job->request.settings().iterations(), 3u);
    EXPECT_EQ(check.job->request.settings().width(), 16u);
    EXPECT_EQ(check.job->request.settings().height(), 4u);
    // A time budget alone does not take the scene's sample_count.
    r.mutable_settings()->set_iterations(0);
    r.mutable_settings()->set_time_budget_seconds(10);
    check = check_submission(r, dir, 120);
    ASSERT_TRUE(check.job);
    EXPECT_EQ(check.job->request.settings().iterations(), 0u);
}

TEST_F(SubmissionCheckTest, AFilmTooLargeIsABadSettingAndNotLogged) {
    v1::SubmitJobRequest r = request();
    r.mutable_settings()->set_width(kMaxFilmResolution + 1);
    const SubmissionCheck check = check_submission(r, dir, 120);
    ASSERT_FALSE(check.job);
    EXPECT_EQ(check.rejection.status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
    EXPECT_EQ(check.rejection.status.error_message(),
              "the film " + std::to_string(kMaxFilmResolution + 1) + "x6 exceeds " +
                  std::to_string(kMaxFilmResolution));
    EXPECT_EQ(check.rejection.log_reason, nullptr);
}

TEST_F(SubmissionCheckTest, TooManyIterationsOverAllFramesAreRefused) {
    v1::SubmitJobRequest r = request();
    r.mutable_settings()->set_iterations(kMaxIterations);
    add_frames(r, {"0.5", "0.5", "0.5", "0.5", "0.5", "0.5", "0.5", "0.5", "0.5", "0.5", "0.5"});
    const SubmissionCheck check = check_submission(r, dir, 120);
    ASSERT_FALSE(check.job);
    EXPECT_EQ(check.rejection.status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
    EXPECT_EQ(check.rejection.status.error_message(), check_job_iterations(kMaxIterations, 11));
}

TEST_F(SubmissionCheckTest, AFrameWhoseSceneFailsIsNamedWithItsOverrides) {
    v1::SubmitJobRequest r = request();
    add_frames(r, {"0.25", "0.5", "oops"});
    const SubmissionCheck check = check_submission(r, dir, 120);
    ASSERT_FALSE(check.job);
    const std::string message = check.rejection.status.error_message();
    EXPECT_EQ(check.rejection.status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
    EXPECT_EQ(message.rfind("frame 2 (r=oops): scene error: scene.xml:", 0), 0u) << message;
    EXPECT_EQ(message.find(dir.string()), std::string::npos) << "names the server's folder";
    EXPECT_STREQ(check.rejection.log_reason, "scene");
    EXPECT_EQ(check.rejection.frame, 2);
}

TEST_F(SubmissionCheckTest, AMissingSceneFileIsAScenesFaultInASingleFrameJob) {
    v1::SubmitJobRequest r = request();
    r.mutable_bundle()->set_scene_path("missing.xml");
    const SubmissionCheck check = check_submission(r, dir, 120);
    ASSERT_FALSE(check.job);
    EXPECT_EQ(check.rejection.status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
    EXPECT_NE(check.rejection.log_reason, nullptr);
    EXPECT_EQ(check.rejection.frame, 0);
    // One frame: no frame prefix.
    EXPECT_NE(check.rejection.status.error_message().rfind("frame ", 0), 0u);
}

TEST_F(SubmissionCheckTest, TheValidationBudgetRefusesAnimationsButNotRepeatedFrames) {
    v1::SubmitJobRequest r = request();
    add_frames(r, {"0.25", "0.5", "0.75"});
    SubmissionCheck check = check_submission(r, dir, 0);
    ASSERT_FALSE(check.job);
    EXPECT_EQ(check.rejection.status.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
    EXPECT_EQ(check.rejection.status.error_message().rfind(
                  "frames: loading the scene of each of 3 distinct frames", 0),
              0u)
        << check.rejection.status.error_message();
    EXPECT_STREQ(check.rejection.log_reason, kValidationBudgetReason);
    // Frames with the same defines as frame 0 give its scene: nothing more to load.
    r.clear_frames();
    add_frames(r, {"0.25", "0.25", "0.25"});
    check = check_submission(r, dir, 0);
    ASSERT_TRUE(check.job) << check.rejection.status.error_message();
    EXPECT_EQ(check.job->frames, 3u);
}

TEST_F(SubmissionCheckTest, AFrameOverridesTheJobsDefines) {
    v1::SubmitJobRequest r = request();
    (*r.mutable_settings()->mutable_defines())["r"] = "0.1";
    (*r.mutable_settings()->mutable_defines())["g"] = "0.2";
    add_frames(r, {"0.3"});
    EXPECT_EQ(frame_defines(r, 0),
              (std::map<std::string, std::string>{{"g", "0.2"}, {"r", "0.3"}}));
    EXPECT_EQ(frame_defines(r, 1),
              (std::map<std::string, std::string>{{"g", "0.2"}, {"r", "0.1"}}));
}

TEST_F(SubmissionCheckTest, EveryBundleFileMustBeAnUploadedAssetOfItsSize) {
    v1::SubmitJobRequest r = request();
    std::map<std::string, uint64_t> stored;
    auto size_of = [&](const std::string& sha) -> std::optional<uint64_t> {
        auto it = stored.find(sha);
        return it == stored.end() ? std::nullopt : std::optional<uint64_t>(it->second);
    };
    grpc::Status st = check_bundle_assets(r, size_of);
    EXPECT_EQ(st.error_code(), grpc::StatusCode::FAILED_PRECONDITION);
    EXPECT_EQ(st.error_message(), "asset \"scene.xml\" (sha256 abc) has not been uploaded");
    stored["abc"] = 10;
    st = check_bundle_assets(r, size_of);
    EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
    EXPECT_EQ(st.error_message(), "bundle file \"scene.xml\" declares 12 bytes, the asset has 10");
    stored["abc"] = 12;
    EXPECT_TRUE(check_bundle_assets(r, size_of).ok());
    r.mutable_bundle()->mutable_files(0)->set_size(0);  // undeclared: any size
    stored["abc"] = 10;
    EXPECT_TRUE(check_bundle_assets(r, size_of).ok());
}
