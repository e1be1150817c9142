// The server's job manager without sockets: submit validation, leases and reports merged
// exactly once, frames finished into EXR, and a restart on the same store resuming the job.

#include <gtest/gtest.h>

#include <atomic>
#include <functional>
#include <thread>

#include <filesystem>

#include "core/image/exr_io.h"
#include "core/render/render_iterations.h"
#include "core/scene/loader/scene_loader.h"
#include "core/util/sha256.h"
#include "server/job_manager.h"
#include "tests/support/server_test_scene.h"

using namespace render;
using namespace render::server;
namespace fs = std::filesystem;
namespace v1 = render::v1;

namespace {

const char* kScene = render::testing::kServerTestScene;

struct ManagerTest : ::testing::Test {
    fs::path dir;
    ServerOptions options;
    void SetUp() override {
        dir = fs::temp_directory_path() /
              ("server_manager_test_" + std::to_string(::getpid()) + "_" +
               ::testing::UnitTest::GetInstance()->current_test_info()->name());
        fs::remove_all(dir);
        options.store = dir;
        options.lease_timeout_seconds = 30;
    }
    void TearDown() override { fs::remove_all(dir); }

    std::string upload(JobManager& m, const std::string& data) {
        std::string sha = sha256_hex(data);
        AssetStore::Upload u(m.assets(), sha, data.size());
        EXPECT_EQ(u.write(data), "");
        EXPECT_EQ(u.commit(), "");
        return sha;
    }

    v1::SubmitJobRequest request(JobManager& m, uint64_t iterations) {
        v1::SubmitJobRequest r;
        r.set_name("test");
        r.mutable_settings()->set_algorithm("pt");
        r.mutable_settings()->set_iterations(iterations);
        r.mutable_bundle()->set_scene_path("scene.xml");
        v1::BundleFile* f = r.mutable_bundle()->add_files();
        f->set_path("scene.xml");
        f->set_sha256(upload(m, kScene));
        f->set_size(std::string(kScene).size());
        return r;
    }

    // Renders a lease like a worker would and reports it.
    // Asks for a lease as worker `worker` (granted or not).
    static v1::LeaseReply lease_for(JobManager& m, const std::string& worker) {
        v1::LeaseRequest lr;
        lr.set_worker_id(worker);
        v1::LeaseReply reply;
        EXPECT_TRUE(m.lease(lr, &reply).ok());
        return reply;
    }

    // Worker `worker` reports in a heartbeat that it could not render `lease` (error `error`).
    static void report_failed_lease(JobManager& m, const std::string& worker,
                                    const v1::LeaseReply& lease, const std::string& error) {
        v1::HeartbeatRequest hb;
        hb.set_worker_id(worker);
        v1::LeaseFailure* f = hb.add_failed_leases();
        f->set_lease_id(lease.lease().lease_id());
        f->set_error(error);
        v1::HeartbeatReply reply;
        EXPECT_TRUE(m.heartbeat(hb, &reply).ok());
    }

    bool render_and_report(JobManager& m, const v1::Lease& lease, double render_seconds = 0.01) {
        auto scene = render::load_scene_from_string(kScene, ".");
        render::RenderSettings s;
        s.algorithm = lease.settings().algorithm();
        s.seed = lease.settings().seed();
        auto r = render::render_iterations(*scene, s, lease.frame(),
                                           {lease.first_iteration(), lease.end_iteration()});
        v1::ReportHeader h;
        h.set_lease_id(lease.lease_id());
        h.set_count(r.count);
        h.set_odd_count(r.odd_count);
        h.set_width(8);
        h.set_height(6);
        h.set_render_seconds(render_seconds);
        size_t n = 0, layers = 0, exact = 0;
        bool drop = false;
        EXPECT_TRUE(m.check_report(h, &n, &layers, &exact, &drop).ok());
        EXPECT_EQ(exact, 0u) << "not an adaptive job: no exact sums";
        if (drop) return false;
        EXPECT_EQ(n, 8u * 6u * 3u);
        EXPECT_EQ(layers, 0u);
        bool merged = false;
        ReportValues values = ReportValues::in_memory(2 * n);
        for (const auto* part : {&r.sum.values(), &r.odd_sum.values()})
            EXPECT_EQ(values.append({reinterpret_cast<const char*>(part->data()),
                                     part->size() * sizeof(double)}),
                      "");
        EXPECT_TRUE(m.report(h, std::move(values), &merged).ok());
        return merged;
    }
};

}  // namespace

TEST_F(ManagerTest, RejectsBadRequestsWithPreciseCodes) {
    JobManager m(options);
    v1::Job job;
    auto good = request(m, 4);

    auto r = good;
    r.mutable_settings()->set_algorithm("magic");
    EXPECT_EQ(m.submit(r, &job).error_code(), grpc::StatusCode::INVALID_ARGUMENT);
    r = good;
    r.mutable_settings()->set_iterations(100000000);
    EXPECT_EQ(m.submit(r, &job).error_code(), grpc::StatusCode::INVALID_ARGUMENT);
    r = good;
    r.mutable_settings()->set_width(100000);
    r.mutable_settings()->set_height(100000);
    EXPECT_EQ(m.submit(r, &job).error_code(), grpc::StatusCode::INVALID_ARGUMENT);
    r = good;
    r.mutable_bundle()->mutable_files(0)->set_path("../../etc/passwd");
    r.mutable_bundle()->set_scene_path("../../etc/passwd");
    EXPECT_EQ(m.submit(r, &job).error_code(), grpc::StatusCode::INVALID_ARGUMENT);
    r = good;
    r.mutable_bundle()->mutable_files(0)->set_sha256(sha256_hex("never uploaded"));
    auto missing = m.submit(r, &job);
    EXPECT_EQ(missing.error_code(), grpc::StatusCode::FAILED_PRECONDITION);
    EXPECT_NE(missing.error_message().find("scene.xml"), std::string::npos);
    r = good;
    std::string broken = "<scene version=\"3.0.0\"><shape type=\"nonsense\"/></scene>";
    r.mutable_bundle()->mutable_files(0)->set_sha256(upload(m, broken));
    r.mutable_bundle()->mutable_files(0)->set_size(broken.size());
    const grpc::Status scene_error = m.submit(r, &job);
    EXPECT_EQ(scene_error.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
    // Named as in the bundle ("scene.xml:1"), never by the server's store folder.
    EXPECT_EQ(scene_error.error_message().rfind("scene error: scene.xml:1: ", 0), 0u)
        << scene_error.error_message();
    EXPECT_EQ(scene_error.error_message().find("jobs/"), std::string::npos)
        << scene_error.error_message();
    r = good;
    for (int i = 0; i < 1001; ++i) r.add_frames();
    EXPECT_EQ(m.submit(r, &job).error_code(), grpc::StatusCode::INVALID_ARGUMENT);
    EXPECT_EQ(m.submit(good, &job).error_code(), grpc::StatusCode::OK);
    EXPECT_EQ(job.state(), v1::JOB_STATE_QUEUED);
    EXPECT_EQ(job.settings().width(), 8u);
    v1::ListJobsReply list;
    m.list(&list);
    EXPECT_EQ(list.jobs_size(), 1);
    EXPECT_EQ(m.get("job-nope", &job).error_code(), grpc::StatusCode::NOT_FOUND);
}

// The options map is checked against the render options table, typed legacy fields are folded
// into it, and the stored job carries every option its algorithm reads.
// Out of line: GCC 12 inlines the map's string assignment into the lambdas below and warns
// about a memcpy it cannot bound (-Wrestrict, a false positive).
[[gnu::noinline]] void set_option(v1::RenderSettings& s, const std::string& name,
                                  const std::string& value) {
    (*s.mutable_options())[name] = value;
}

TEST_F(ManagerTest, OptionsAreCheckedAndStoredComplete) {
    JobManager m(options);
    v1::Job job;
    auto good = request(m, 4);
    auto refused = [&](const std::function<void(v1::RenderSettings&)>& change,
                       const std::string& expected) {
        auto r = good;
        change(*r.mutable_settings());
        grpc::Status st = m.submit(r, &job);
        EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << expected;
        EXPECT_NE(st.error_message().find(expected), std::string::npos) << st.error_message();
    };
    refused([](v1::RenderSettings& s) { set_option(s, "radius", "1"); }, "radius");
    refused([](v1::RenderSettings& s) { set_option(s, "mis", "maybe"); }, "mis");
    refused([](v1::RenderSettings& s) { set_option(s, "alpha", "1.5"); }, "alpha");
    refused(
        [](v1::RenderSettings& s) {
            s.set_algorithm("pt");
            set_option(s, "radius_factor", "0.01");
        },
        "radius_factor");
    refused(
        [](v1::RenderSettings& s) {
            s.set_algorithm("vcm");
            s.set_alpha(0.5);
            set_option(s, "alpha", "0.6");
        },
        "disagree");

    auto r = good;
    r.mutable_settings()->set_algorithm("vcm");
    r.mutable_settings()->set_alpha(0.5);  // a typed field of older clients
    (*r.mutable_settings()->mutable_options())["mis"] = "balance";
    ASSERT_TRUE(m.submit(r, &job).ok());
    const auto& stored = job.settings().options();
    EXPECT_EQ(stored.at("alpha"), "0.5");
    EXPECT_EQ(stored.at("mis"), "balance");
    EXPECT_EQ(stored.at("radius_pixels"), "1");  // the default, made explicit
    EXPECT_EQ(stored.count("equiangular"), 0u);  // vcm does not read it
    EXPECT_EQ(job.settings().alpha(), 0.0);      // folded into the map
    r = good;
    r.mutable_settings()->set_algorithm("path");  // an alias is stored by its name
    ASSERT_TRUE(m.submit(r, &job).ok());
    EXPECT_EQ(job.settings().algorithm(), "pt");
}

TEST_F(ManagerTest, RendersAJobAndDropsDuplicates) {
    JobManager m(options);
    v1::Job job;
    ASSERT_TRUE(m.submit(request(m, 5), &job).ok());
    v1::RegisterWorkerReply reg;
    m.register_worker({}, &reg);
    v1::LeaseRequest lr;
    lr.set_worker_id(reg.worker_id());
    v1::LeaseReply first;
    ASSERT_TRUE(m.lease(lr, &first).ok());
    ASSERT_TRUE(first.granted());
    EXPECT_EQ(first.lease().first_iteration(), 1u);
    EXPECT_EQ(first.lease().end_iteration(), 2u);
    EXPECT_TRUE(render_and_report(m, first.lease()));
    EXPECT_FALSE(render_and_report(m, first.lease()));  // duplicate: dropped

    v1::FetchResultRequest fr;
    fr.set_job_id(job.id());
    fs::path file;
    bool temporary = false;
    EXPECT_EQ(m.result_file(fr, &file, &temporary).error_code(),
              grpc::StatusCode::FAILED_PRECONDITION);
    fr.set_preview(true);
    ASSERT_TRUE(m.result_file(fr, &file, &temporary).ok());
    EXPECT_TRUE(temporary);
    EXPECT_TRUE(fs::exists(file));

    v1::LeaseReply next;
    while (m.lease(lr, &next).ok() && next.granted()) {
        EXPECT_TRUE(render_and_report(m, next.lease()));
        next.Clear();
    }
    ASSERT_TRUE(m.get(job.id(), &job).ok());
    EXPECT_EQ(job.state(), v1::JOB_STATE_DONE);
    EXPECT_EQ(job.frames(0).iterations_done(), 5u);
    fr.set_preview(false);
    ASSERT_TRUE(m.result_file(fr, &file, &temporary).ok());
    EXPECT_FALSE(temporary);
    EXPECT_TRUE(fs::exists(file));
    fr.set_frame(3);
    EXPECT_EQ(m.result_file(fr, &file, &temporary).error_code(), grpc::StatusCode::NOT_FOUND);
}

TEST_F(ManagerTest, RestartResumesFromTheCheckpoint) {
    options.checkpoint_seconds = 0;  // a checkpoint after every report
    std::string id;
    v1::Lease stale;
    {
        JobManager m(options);
        v1::Job job;
        ASSERT_TRUE(m.submit(request(m, 6), &job).ok());
        id = job.id();
        v1::LeaseRequest lr;
        lr.set_worker_id("w-1");
        v1::LeaseReply a, b;
        ASSERT_TRUE(m.lease(lr, &a).ok());
        ASSERT_TRUE(render_and_report(m, a.lease()));  // [1, 2) merged
        ASSERT_TRUE(m.lease(lr, &b).ok());
        stale = b.lease();  // outstanding at the "crash"
    }
    JobManager m(options);
    v1::Job job;
    ASSERT_TRUE(m.get(id, &job).ok());
    EXPECT_EQ(job.frames(0).iterations_done(), 1u);
    EXPECT_FALSE(render_and_report(m, stale));  // a lease of the previous run is void
    v1::LeaseRequest lr;
    lr.set_worker_id("w-2");
    v1::LeaseReply next;
    ASSERT_TRUE(m.lease(lr, &next).ok());
    EXPECT_EQ(next.lease().first_iteration(), 2u);  // the voided range comes back
    EXPECT_TRUE(render_and_report(m, next.lease()));
    next.Clear();
    while (m.lease(lr, &next).ok() && next.granted()) {
        EXPECT_TRUE(render_and_report(m, next.lease()));
        next.Clear();
    }
    ASSERT_TRUE(m.get(id, &job).ok());
    EXPECT_EQ(job.state(), v1::JOB_STATE_DONE);
    EXPECT_EQ(job.frames(0).iterations_done(), 6u);
}

TEST_F(ManagerTest, CancelTellsWorkersThroughHeartbeats) {
    JobManager m(options);
    v1::Job job;
    ASSERT_TRUE(m.submit(request(m, 50), &job).ok());
    v1::LeaseRequest lr;
    lr.set_worker_id("w-1");
    v1::LeaseReply a;
    ASSERT_TRUE(m.lease(lr, &a).ok());
    ASSERT_TRUE(m.cancel(job.id(), &job).ok());
    EXPECT_EQ(job.state(), v1::JOB_STATE_CANCELLED);
    v1::HeartbeatRequest hb;
    hb.set_worker_id("w-1");
    hb.add_lease_ids(a.lease().lease_id());
    v1::HeartbeatReply reply;
    ASSERT_TRUE(m.heartbeat(hb, &reply).ok());
    ASSERT_EQ(reply.cancelled_lease_ids_size(), 1);
    EXPECT_FALSE(render_and_report(m, a.lease()));
    v1::LeaseReply none;
    ASSERT_TRUE(m.lease(lr, &none).ok());
    EXPECT_FALSE(none.granted());
}

// A worker that cannot render a lease says so in a heartbeat: the range is handed out again at
// once (not after the lease expires), and once two distinct workers (or every worker the server
// knows, if fewer) failed the job since its last merged report it FAILS with the last error
// instead of being leased for ever (a poison scene would otherwise keep every worker busy
// failing).
TEST_F(ManagerTest, LeasesFailedOnTwoWorkersFailTheJob) {
    JobManager m(options);
    v1::Job job;
    ASSERT_TRUE(m.submit(request(m, 50), &job).ok());
    auto lease_for = [&](const std::string& worker) { return ManagerTest::lease_for(m, worker); };
    auto fail = [&](const std::string& worker, const v1::LeaseReply& lease,
                    const std::string& error) { report_failed_lease(m, worker, lease, error); };
    auto state = [&] {
        EXPECT_TRUE(m.get(job.id(), &job).ok());
        return job.state();
    };
    const v1::LeaseReply a1 = lease_for("w-1"), a2 = lease_for("w-2"), a3 = lease_for("w-3");
    ASSERT_TRUE(a1.granted() && a2.granted() && a3.granted());

    fail("w-2", a1, "not my lease");  // ignored: only the holder can give a lease up
    EXPECT_EQ(state(), v1::JOB_STATE_RUNNING);
    fail("w-1", a1, "boom on w-1");
    EXPECT_EQ(state(), v1::JOB_STATE_RUNNING);
    // The failed range is handed out again at once.
    const v1::LeaseReply b = lease_for("w-1");
    ASSERT_TRUE(b.granted());
    EXPECT_EQ(b.lease().first_iteration(), a1.lease().first_iteration());
    fail("w-1", b, "boom on w-1 again");  // the same worker counts once
    EXPECT_EQ(state(), v1::JOB_STATE_RUNNING);
    // A merged report means the job renders somewhere: the failures so far stop counting.
    EXPECT_TRUE(render_and_report(m, a2.lease()));
    fail("w-3", a3, "boom on w-3");  // one worker since the merge
    EXPECT_EQ(state(), v1::JOB_STATE_RUNNING);
    const v1::LeaseReply d = lease_for("w-1");
    ASSERT_TRUE(d.granted());
    fail("w-1", d, "boom on w-1");
    EXPECT_EQ(state(), v1::JOB_STATE_FAILED);
    EXPECT_NE(job.error().find("failed on 2 workers"), std::string::npos) << job.error();
    EXPECT_NE(job.error().find("boom on w-1"), std::string::npos) << job.error();
    EXPECT_FALSE(lease_for("w-2").granted());
}

// A lease that expires (its worker died, e.g. killed by the scene it renders, or hung on it)
// counts against the job as a failed lease does, but only three distinct workers fail the job,
// whatever the number of workers known (one worker restarted by systemd gets a new id each
// time; a single loss may be a machine taken away). A merged report clears the count.
TEST_F(ManagerTest, LeasesLostOnThreeWorkersFailTheJob) {
    TimePoint now = SteadyClock::now();
    JobManager m(options, [&] { return now; });
    v1::Job job;
    ASSERT_TRUE(m.submit(request(m, 200), &job).ok());
    auto lease_for = [&](const std::string& worker) { return ManagerTest::lease_for(m, worker); };
    auto expire_all = [&] {
        now += std::chrono::seconds(int(options.lease_timeout_seconds) + 1);
        m.tick();
    };
    auto state = [&] {
        EXPECT_TRUE(m.get(job.id(), &job).ok());
        return job.state();
    };
    ASSERT_TRUE(lease_for("w-1").granted());
    expire_all();
    EXPECT_EQ(state(), v1::JOB_STATE_RUNNING);  // the only known worker: not enough
    ASSERT_TRUE(lease_for("w-2").granted());
    expire_all();
    EXPECT_EQ(state(), v1::JOB_STATE_RUNNING);
    // A merged report: the job renders somewhere, the losses so far stop counting.
    const v1::LeaseReply merged = lease_for("w-3");
    ASSERT_TRUE(merged.granted());
    EXPECT_TRUE(render_and_report(m, merged.lease()));
    ASSERT_TRUE(lease_for("w-3").granted());  // the rest of the frame (w-3's rate is known)
    expire_all();
    EXPECT_EQ(state(), v1::JOB_STATE_RUNNING);
    ASSERT_TRUE(lease_for("w-4").granted());
    expire_all();
    EXPECT_EQ(state(), v1::JOB_STATE_RUNNING);
    // A third: a worker reporting a failure counts with the lost ones.
    const v1::LeaseReply last = lease_for("w-5");
    ASSERT_TRUE(last.granted());
    report_failed_lease(m, "w-5", last, "renderer: out of memory");
    EXPECT_EQ(state(), v1::JOB_STATE_FAILED);
    EXPECT_NE(job.error().find("failed on 3 workers (2 lost the lease"), std::string::npos)
        << job.error();
    EXPECT_NE(job.error().find("out of memory"), std::string::npos) << job.error();
}

// Workers lost after they reported progress on the lease (preempted while rendering fine) count
// toward failing the job only at 10 distinct workers.
TEST_F(ManagerTest, LeasesLostAfterProgressFailTheJobOnlyAtTen) {
    TimePoint now = SteadyClock::now();
    JobManager m(options, [&] { return now; });
    v1::Job job;
    ASSERT_TRUE(m.submit(request(m, 200), &job).ok());
    auto state = [&] {
        EXPECT_TRUE(m.get(job.id(), &job).ok());
        return job.state();
    };
    for (int w = 1; w <= 10; ++w) {
        const std::string worker = "w-" + std::to_string(w);
        const v1::LeaseReply lease = lease_for(m, worker);
        ASSERT_TRUE(lease.granted());
        v1::HeartbeatRequest beat;
        beat.set_worker_id(worker);
        beat.add_lease_ids(lease.lease().lease_id());
        beat.mutable_rates()->set_iterations_per_second(10);
        v1::HeartbeatReply reply;
        ASSERT_TRUE(m.heartbeat(beat, &reply).ok());
        now += std::chrono::seconds(int(options.lease_timeout_seconds) + 1);
        m.tick();
        EXPECT_EQ(state(), w < 10 ? v1::JOB_STATE_RUNNING : v1::JOB_STATE_FAILED) << worker;
    }
    EXPECT_NE(job.error().find("failed on 10 workers (10 lost the lease"), std::string::npos)
        << job.error();
}

// With fewer workers than three, the job fails once every worker the server knows failed it.
TEST_F(ManagerTest, ALeaseFailedOnTheOnlyWorkerFailsTheJob) {
    JobManager m(options);
    v1::Job job;
    ASSERT_TRUE(m.submit(request(m, 50), &job).ok());
    v1::LeaseRequest lr;
    lr.set_worker_id("w-1");
    v1::LeaseReply a;
    ASSERT_TRUE(m.lease(lr, &a).ok());
    report_failed_lease(m, "w-1", a, "scene error: scene.xml:3: cannot load");
    ASSERT_TRUE(m.get(job.id(), &job).ok());
    EXPECT_EQ(job.state(), v1::JOB_STATE_FAILED);
    EXPECT_NE(job.error().find("scene.xml:3"), std::string::npos) << job.error();
}

TEST_F(ManagerTest, ValidatesEveryFrameOfAnAnimation) {
    JobManager m(options);
    v1::Job job;
    auto r = request(m, 2);
    for (const char* value : {"0.25", "0.5", "0.75"})
        (*r.add_frames()->mutable_defines())["r"] = value;
    ASSERT_TRUE(m.submit(r, &job).ok());
    EXPECT_EQ(job.frames_size(), 3);
    // Frame 2's define breaks the scene: refused, naming frame 2 and its override.
    (*r.mutable_frames(2)->mutable_defines())["r"] = "oops";
    const grpc::Status bad = m.submit(r, &job);
    EXPECT_EQ(bad.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
    EXPECT_EQ(bad.error_message().rfind("frame 2 (r=oops): scene error: scene.xml:", 0), 0u)
        << bad.error_message();
    v1::ListJobsReply list;
    m.list(&list);
    EXPECT_EQ(list.jobs_size(), 1);
    // A single frame is never refused for the validation budget; an animation is.
    options.submit_validation_seconds = 1e-9;
    options.store = dir / "tight";
    JobManager tight(options);
    r = request(tight, 2);
    for (const char* value : {"0.25", "0.5", "0.75"})
        (*r.add_frames()->mutable_defines())["r"] = value;
    EXPECT_EQ(tight.submit(r, &job).error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
    r.clear_frames();
    EXPECT_TRUE(tight.submit(r, &job).ok());
}

namespace {

struct FakeClock {
    TimePoint now = TimePoint{} + std::chrono::hours(1);
    void advance(double seconds) {
        now += std::chrono::duration_cast<SteadyClock::duration>(
            std::chrono::duration<double>(seconds));
    }
};

// A one-iteration lease for `worker` (the worker's rate is unknown, or 3 s per iteration).
v1::Lease one_iteration(JobManager& m, const std::string& worker) {
    v1::LeaseRequest lr;
    lr.set_worker_id(worker);
    v1::LeaseReply reply;
    EXPECT_TRUE(m.lease(lr, &reply).ok());
    EXPECT_TRUE(reply.granted());
    EXPECT_EQ(reply.lease().end_iteration() - reply.lease().first_iteration(), 1u);
    return reply.lease();
}

uint64_t iterations_done(JobManager& m, const std::string& id) {
    v1::Job job;
    EXPECT_TRUE(m.get(id, &job).ok());
    return job.frames(0).iterations_done();
}

}  // namespace

namespace {

// Worker `worker` refuses `lease` for memory: its estimate of 10 MiB over its limit.
void refuse_for_memory(JobManager& m, const std::string& worker, const v1::LeaseReply& lease,
                       uint64_t limit) {
    v1::HeartbeatRequest hb;
    hb.set_worker_id(worker);
    v1::LeaseFailure* f = hb.add_failed_leases();
    f->set_lease_id(lease.lease().lease_id());
    f->set_error("the film (512 x 512): the scene needs at least 10.0 MiB of memory");
    f->set_memory_needed(10 << 20);
    f->set_memory_limit(limit);
    v1::HeartbeatReply reply;
    EXPECT_TRUE(m.heartbeat(hb, &reply).ok());
}

}  // namespace

// A refusal for memory is not a failure (docs/guide/service.md, "Workers"): on the only worker it
// does not fail the job (a failure would: ALeaseFailedOnTheOnlyWorkerFailsTheJob); the job is not
// offered to that worker again, says what it waits for, and FAILS once every live worker refused it
// for --memory-wait seconds (of the injected clock).
TEST_F(ManagerTest, AJobRefusedForMemoryByEveryWorkerFailsAfterTheMemoryWait) {
    FakeClock clock;
    options.memory_wait_seconds = 60;
    JobManager m(options, [&] { return clock.now; });
    v1::Job job;
    ASSERT_TRUE(m.submit(request(m, 50), &job).ok());
    const v1::LeaseReply a = lease_for(m, "w-small");
    ASSERT_TRUE(a.granted());
    refuse_for_memory(m, "w-small", a, 4 << 20);
    EXPECT_FALSE(lease_for(m, "w-small").granted());
    m.tick();
    clock.advance(59);
    m.tick();
    ASSERT_TRUE(m.get(job.id(), &job).ok());
    EXPECT_EQ(job.state(), v1::JOB_STATE_WAITING) << job.error();
    EXPECT_NE(job.waiting().find("waiting for a worker with more than 4.0 MiB of memory: the "
                                 "job needs at least 10.0 MiB (refused for memory by 1 worker;"),
              std::string::npos)
        << job.waiting();
    clock.advance(2);
    m.tick();
    ASSERT_TRUE(m.get(job.id(), &job).ok());
    EXPECT_EQ(job.state(), v1::JOB_STATE_FAILED);
    EXPECT_NE(job.error().find("no worker has the memory for this job: refused for memory by 1 "
                               "worker and no live worker with more joined within 60 s"),
              std::string::npos)
        << job.error();
    EXPECT_NE(job.error().find("the film (512 x 512)"), std::string::npos) << job.error();
}

// A worker that has not refused the job stops the wait, gets the refused range and renders it.
TEST_F(ManagerTest, AJobRefusedForMemoryGoesToALargerWorker) {
    FakeClock clock;
    options.memory_wait_seconds = 60;
    JobManager m(options, [&] { return clock.now; });
    v1::Job job;
    ASSERT_TRUE(m.submit(request(m, 50), &job).ok());
    const v1::LeaseReply a = lease_for(m, "w-small");
    ASSERT_TRUE(a.granted());
    refuse_for_memory(m, "w-small", a, 4 << 20);
    m.tick();
    clock.advance(50);
    m.tick();
    const v1::LeaseReply b = lease_for(m, "w-large");
    ASSERT_TRUE(b.granted());
    EXPECT_EQ(b.lease().first_iteration(), a.lease().first_iteration());
    ASSERT_TRUE(m.get(job.id(), &job).ok());
    EXPECT_EQ(job.waiting(), "");
    clock.advance(20);  // past the wait since the refusal, not blocked: still running
    m.tick();
    ASSERT_TRUE(m.get(job.id(), &job).ok());
    EXPECT_EQ(job.state(), v1::JOB_STATE_RUNNING) << job.error();
    EXPECT_TRUE(render_and_report(m, b.lease()));
}

// Checkpoints every 10 s (of an injected clock): the store records only what the checkpoint
// holds, so after a crash exactly the ranges merged since the last checkpoint are leased
// again (a gap below merged ranges included), none is counted twice, and the image is
// `render`'s.
TEST_F(ManagerTest, RangesMergedAfterTheLastCheckpointAreLeasedAgainAfterACrash) {
    options.checkpoint_seconds = 10;
    FakeClock clock;
    std::string id;
    const fs::path ckpt_dir = dir / "checkpoints";
    {
        JobManager m(options, [&] { return clock.now; });
        v1::Job job;
        ASSERT_TRUE(m.submit(request(m, 6), &job).ok());
        id = job.id();
        const v1::Lease a = one_iteration(m, "w-1");  // [1, 2)
        const v1::Lease b = one_iteration(m, "w-2");  // [2, 3)
        const v1::Lease c = one_iteration(m, "w-3");  // [3, 4)
        ASSERT_EQ(b.first_iteration(), 2u);
        ASSERT_EQ(c.first_iteration(), 3u);
        ASSERT_TRUE(render_and_report(m, a, 3));  // the interval starts: no checkpoint yet
        EXPECT_FALSE(fs::exists(ckpt_dir / id / "0.ckpt"));
        clock.advance(10);
        ASSERT_TRUE(render_and_report(m, c, 3));  // the report does not write it (a worker
        EXPECT_FALSE(fs::exists(ckpt_dir / id / "0.ckpt"));  // waits for the reply)...
        m.tick();  // ...the tick does, 10 s after the first merge: [1, 2) + [3, 4)
        EXPECT_TRUE(fs::exists(ckpt_dir / id / "0.ckpt"));
        ASSERT_TRUE(render_and_report(m, b, 3));  // [2, 3): merged, not checkpointed
        clock.advance(9);
        m.tick();  // 9 s since the checkpoint: not due
        EXPECT_EQ(iterations_done(m, id), 3u);
    }  // a crash: no checkpoint_all
    {
        JobManager m(options, [&] { return clock.now; });
        EXPECT_EQ(iterations_done(m, id), 2u);  // what the checkpoint holds
        // The lost range comes back first, then the iterations never handed out.
        const v1::Lease again = one_iteration(m, "w-4");
        EXPECT_EQ(again.first_iteration(), 2u);
        const v1::Lease next = one_iteration(m, "w-5");
        EXPECT_EQ(next.first_iteration(), 4u);
        ASSERT_TRUE(render_and_report(m, again, 3));
        ASSERT_TRUE(render_and_report(m, next, 3));
        EXPECT_EQ(iterations_done(m, id), 4u);
        clock.advance(10);
        m.tick();  // due: [1, 5) checkpointed without a new report
    }
    JobManager m(options, [&] { return clock.now; });
    EXPECT_EQ(iterations_done(m, id), 4u);
    v1::LeaseRequest lr;
    lr.set_worker_id("w-6");
    v1::LeaseReply next;
    uint64_t first = 0;
    while (m.lease(lr, &next).ok() && next.granted()) {
        if (first == 0) first = next.lease().first_iteration();
        EXPECT_TRUE(render_and_report(m, next.lease(), 3));
        next.Clear();
    }
    EXPECT_EQ(first, 5u);
    v1::Job job;
    ASSERT_TRUE(m.get(id, &job).ok());
    ASSERT_EQ(job.state(), v1::JOB_STATE_DONE);
    EXPECT_EQ(job.frames(0).iterations_done(), 6u);
    // The image is the mean of iterations 1..6 exactly once each.
    v1::FetchResultRequest fr;
    fr.set_job_id(id);
    fs::path file;
    bool temporary = false;
    ASSERT_TRUE(m.result_file(fr, &file, &temporary).ok());
    const Image image = read_image(file);
    auto scene = render::load_scene_from_string(kScene, ".");
    render::RenderSettings s;
    s.algorithm = "pt";
    s.seed = job.settings().seed();  // as render_and_report renders
    const Image expected = render::render_iterations(*scene, s, 0, {1, 7}).sum.average(6);
    ASSERT_EQ(image.pixel_count(), expected.pixel_count());
    for (size_t i = 0; i < image.pixel_count(); ++i) {
        const Rgb a = image.at(i), e = expected.at(i);
        EXPECT_NEAR(a.r, e.r, 1e-6f * std::max(1.0f, std::abs(e.r))) << "pixel " << i;
        EXPECT_NEAR(a.g, e.g, 1e-6f * std::max(1.0f, std::abs(e.g))) << "pixel " << i;
        EXPECT_NEAR(a.b, e.b, 1e-6f * std::max(1.0f, std::abs(e.b))) << "pixel " << i;
    }
}

// A server stopped with SIGTERM writes every frame's pending checkpoint: nothing merged is lost.
TEST_F(ManagerTest, CheckpointAllSavesWhatMergedSinceTheLastCheckpoint) {
    options.checkpoint_seconds = 30;
    FakeClock clock;
    std::string id;
    {
        JobManager m(options, [&] { return clock.now; });
        v1::Job job;
        ASSERT_TRUE(m.submit(request(m, 10), &job).ok());
        id = job.id();
        for (int i = 0; i < 3; ++i) {
            ASSERT_TRUE(render_and_report(m, one_iteration(m, "w-1"), 3));
            clock.advance(1);
        }
        m.tick();
        EXPECT_FALSE(fs::exists(dir / "checkpoints" / id / "0.ckpt"));
        m.checkpoint_all();
    }
    JobManager m(options, [&] { return clock.now; });
    EXPECT_EQ(iterations_done(m, id), 3u);
    EXPECT_EQ(one_iteration(m, "w-2").first_iteration(), 4u);
}

// A checkpoint that took 1 s (of the injected clock) puts the frame's next one 50 s later, not
// checkpoint_seconds (10) later: checkpoints take at most 2 % of the time however large the
// frame.
TEST_F(ManagerTest, ASlowCheckpointSpacesTheNextOnes) {
    options.checkpoint_seconds = 10;
    FakeClock clock;
    double step = 0;  // seconds the clock moves at each reading
    auto now = [&] {
        clock.advance(step);
        return clock.now;
    };
    std::string id;
    {
        JobManager m(options, now);
        v1::Job job;
        ASSERT_TRUE(m.submit(request(m, 10), &job).ok());
        id = job.id();
        ASSERT_TRUE(render_and_report(m, one_iteration(m, "w-1"), 3));
        clock.advance(10);
        step = 1;  // the checkpoint's two readings of the clock are 1 s apart
        m.tick();
        step = 0;
        ASSERT_TRUE(render_and_report(m, one_iteration(m, "w-1"), 3));
        clock.advance(40);
        m.tick();  // 40 s < 50 s: not due
    }
    {
        JobManager m(options, now);
        EXPECT_EQ(iterations_done(m, id), 1u);
        ASSERT_TRUE(render_and_report(m, one_iteration(m, "w-1"), 3));  // [2, 3) again
        clock.advance(10);
        m.tick();  // a fast checkpoint: the next is due checkpoint_seconds later
        ASSERT_TRUE(render_and_report(m, one_iteration(m, "w-1"), 3));
        clock.advance(10);
        m.tick();
    }
    JobManager m(options, now);
    EXPECT_EQ(iterations_done(m, id), 3u);
}

namespace {

// Leases and reports as worker `worker` until nothing more is granted.
void render_all(ManagerTest& t, JobManager& m, const std::string& worker) {
    for (int i = 0; i < 100; ++i) {
        const v1::LeaseReply reply = ManagerTest::lease_for(m, worker);
        if (!reply.granted()) return;
        ASSERT_TRUE(t.render_and_report(m, reply.lease()));
    }
    FAIL() << "the job never stopped granting leases";
}

bool job_exists(JobManager& m, const std::string& id) {
    v1::Job job;
    return m.get(id, &job).ok();
}

}  // namespace

// Retention (--retain-finished 1 h), on an injected clock: each job is deleted an hour after
// it finished (not after it was submitted), through DeleteJob's code (rows, folders), counted
// in the metrics, and the finish time survives a restart. (The manager's wall clock starts at
// the real time of its construction, so the times below keep 10 s of margin.)
TEST_F(ManagerTest, RetentionDeletesJobsAnHourAfterTheyFinished) {
    options.retain_finished_seconds = 3600;
    FakeClock clock;
    std::string done_id, cancelled_id, running_id;
    {
        JobManager m(options, [&] { return clock.now; });
        v1::Job job;
        ASSERT_TRUE(m.submit(request(m, 3), &job).ok());
        done_id = job.id();
        render_all(*this, m, "w-1");
        ASSERT_TRUE(m.get(done_id, &job).ok());
        ASSERT_EQ(job.state(), v1::JOB_STATE_DONE);
        m.tick();
    }
    // A restart: the finish time comes from the store.
    JobManager m(options, [&] { return clock.now; });
    v1::Job job;
    ASSERT_TRUE(m.submit(request(m, 1000), &job).ok());  // never finishes: never deleted
    running_id = job.id();
    clock.advance(1800);  // submitted and cancelled half an hour after the first finished
    ASSERT_TRUE(m.submit(request(m, 3), &job).ok());
    cancelled_id = job.id();
    ASSERT_TRUE(m.cancel(cancelled_id, &job).ok());
    m.tick();
    EXPECT_TRUE(fs::exists(dir / "jobs" / done_id));
    clock.advance(1790);  // 59:50 after the first finished
    m.tick();
    EXPECT_TRUE(job_exists(m, done_id));
    clock.advance(20);  // 60:10
    m.tick();
    EXPECT_FALSE(job_exists(m, done_id));
    EXPECT_FALSE(fs::exists(dir / "jobs" / done_id));
    EXPECT_FALSE(fs::exists(dir / "results" / done_id));
    EXPECT_TRUE(job_exists(m, cancelled_id));
    EXPECT_NE(m.metrics_text().find("render_jobs_expired_total 1\n"), std::string::npos);
    clock.advance(1800);  // 60:10 after the cancel
    m.tick();
    EXPECT_FALSE(job_exists(m, cancelled_id));
    EXPECT_TRUE(job_exists(m, running_id));
    EXPECT_NE(m.metrics_text().find("render_jobs_expired_total 2\n"), std::string::npos);
    // The shared scene asset stays with the job that still uses it.
    EXPECT_TRUE(m.assets().has(sha256_hex(kScene)));
}

// Without --retain-finished (the default) nothing is ever deleted by time.
TEST_F(ManagerTest, WithoutRetentionFinishedJobsStay) {
    FakeClock clock;
    JobManager m(options, [&] { return clock.now; });
    v1::Job job;
    ASSERT_TRUE(m.submit(request(m, 2), &job).ok());
    render_all(*this, m, "w-1");
    clock.advance(10 * 365 * 86400.0);
    m.tick();
    EXPECT_TRUE(job_exists(m, job.id()));
}

// The asset sweep (--unreferenced-asset-grace 1 h) on an injected clock: an asset uploaded and
// never submitted goes an hour after it was last uploaded or named in HasAssets; an asset a job
// references stays; the store's size and the metrics follow.
TEST_F(ManagerTest, AssetsNoJobReferencesGoAfterTheGracePeriod) {
    options.unreferenced_asset_seconds = 3600;
    FakeClock clock;
    JobManager m(options, [&] { return clock.now; });
    v1::Job job;
    ASSERT_TRUE(m.submit(request(m, 1000), &job).ok());
    const std::string orphan = "never submitted";
    const std::string sha = upload(m, orphan);
    m.asset_added(sha, orphan.size());
    const uint64_t stored = m.assets().stored_bytes();
    m.tick();
    clock.advance(3590);
    m.tick();
    EXPECT_TRUE(m.assets().has(sha));
    // A client asks HasAssets at 59:50: it is about to submit a job naming the asset.
    v1::HasAssetsRequest ask;
    ask.add_sha256(sha);
    v1::HasAssetsReply missing;
    m.has_assets(ask, &missing);
    EXPECT_EQ(missing.missing_size(), 0);
    clock.advance(70);  // 61:00 after the upload, 1:10 after HasAssets (a sweep is due: the
    m.tick();           // sweeps come every quarter of the grace, at most every 60 s)
    EXPECT_TRUE(m.assets().has(sha));
    clock.advance(3600);  // 61:10 after HasAssets
    m.tick();
    EXPECT_FALSE(m.assets().has(sha));
    EXPECT_TRUE(m.assets().has(sha256_hex(kScene)));  // the job's
    EXPECT_EQ(m.assets().stored_bytes(), stored - orphan.size());
    const std::string text = m.metrics_text();
    EXPECT_NE(text.find("render_assets_collected_total 1\n"), std::string::npos) << text;
    EXPECT_NE(
        text.find("render_assets_collected_bytes_total " + std::to_string(orphan.size()) + "\n"),
        std::string::npos);
    m.has_assets(ask, &missing);
    EXPECT_EQ(missing.missing_size(), 1);  // the client uploads it again
}

// A submit in progress pins its bundle's assets: sweeps that run while it validates (here its
// 400 frames, each a scene load) never remove them, though no stored job references them yet
// and they are far past the grace period; the job is accepted and its assets stay.
TEST_F(ManagerTest, TheAssetSweepNeverRemovesTheAssetsOfASubmitInProgress) {
    options.unreferenced_asset_seconds = 1;
    std::atomic<int64_t> now_ms{0};
    auto clock = [&] { return TimePoint{} + std::chrono::milliseconds(now_ms.load()); };
    JobManager m(options, clock);
    v1::SubmitJobRequest r = request(m, 1);
    for (int i = 0; i < 400; ++i)
        (*r.add_frames()->mutable_defines())["r"] = std::to_string(0.001 * (i + 1));
    std::atomic<bool> done{false};
    grpc::Status status;
    v1::Job job;
    std::thread submit([&] {
        status = m.submit(r, &job);
        done = true;
    });
    // The sweeps start once the submit has checked its assets and placed its files (its job
    // folder exists); a sweep before that may remove them, and the submit then fails cleanly
    // with FAILED_PRECONDITION (the client uploads them again).
    while (!done.load() && fs::is_empty(dir / "jobs"))
        std::this_thread::sleep_for(std::chrono::microseconds(200));
    int sweeps_during_submit = 0;
    while (!done.load()) {
        now_ms += 10'000;  // every asset is 10 s older: past the 1-s grace
        m.tick();          // a sweep every call (it paces itself by 0.5 s of this clock)
        if (!done.load()) ++sweeps_during_submit;
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    submit.join();
    EXPECT_TRUE(status.ok()) << status.error_message();
    EXPECT_TRUE(m.assets().has(sha256_hex(kScene)));
    // Not a proof by itself: the submit must have been swept over (the load of 400 frames
    // takes far longer than a tick).
    EXPECT_GT(sweeps_during_submit, 0);
    // Once stored, the job references it: later sweeps keep it too.
    now_ms += 10'000;
    m.tick();
    EXPECT_TRUE(m.assets().has(sha256_hex(kScene)));
}

// A job every live worker refused for memory shows WAITING (not RUNNING, though it was leased)
// once no worker holds a lease of it, in GetJob, ListJobs, ClusterStatus and the metrics; with
// a lease still held it shows RUNNING; a larger worker's lease makes it RUNNING again.
TEST_F(ManagerTest, AJobRefusedForMemoryWithNoLeaseHeldShowsWaiting) {
    FakeClock clock;
    options.memory_wait_seconds = 600;
    JobManager m(options, [&] { return clock.now; });
    v1::Job job;
    ASSERT_TRUE(m.submit(request(m, 50), &job).ok());
    const v1::LeaseReply a = lease_for(m, "w-small");  // rendered
    const v1::LeaseReply b = lease_for(m, "w-small");  // refused for memory
    ASSERT_TRUE(a.granted());
    ASSERT_TRUE(b.granted());
    refuse_for_memory(m, "w-small", b, 4 << 20);
    auto shown = [&] {
        v1::Job j;
        EXPECT_TRUE(m.get(job.id(), &j).ok());
        return j;
    };
    EXPECT_EQ(shown().state(), v1::JOB_STATE_RUNNING);  // lease a is still rendering
    EXPECT_NE(shown().waiting(), "");
    ASSERT_TRUE(render_and_report(m, a.lease()));
    EXPECT_EQ(shown().state(), v1::JOB_STATE_WAITING);
    v1::ListJobsReply list;
    m.list(&list);
    ASSERT_EQ(list.jobs_size(), 1);
    EXPECT_EQ(list.jobs(0).state(), v1::JOB_STATE_WAITING);
    v1::ClusterStatusReply status;
    m.cluster_status(&status);
    EXPECT_EQ(status.waiting_jobs(), 1u);
    EXPECT_EQ(status.running_jobs(), 0u);
    EXPECT_EQ(status.queued_jobs(), 0u);
    std::string text = m.metrics_text();
    EXPECT_NE(text.find("render_jobs{state=\"waiting\"} 1\n"), std::string::npos) << text;
    EXPECT_NE(text.find("render_jobs{state=\"running\"} 0\n"), std::string::npos);
    // Not final: a larger worker takes it.
    const v1::LeaseReply c = lease_for(m, "w-large");
    ASSERT_TRUE(c.granted());
    EXPECT_EQ(shown().state(), v1::JOB_STATE_RUNNING);
    EXPECT_EQ(shown().waiting(), "");
    text = m.metrics_text();
    EXPECT_NE(text.find("render_jobs{state=\"running\"} 1\n"), std::string::npos) << text;
    EXPECT_NE(text.find("render_jobs{state=\"waiting\"} 0\n"), std::string::npos);
}

// A report the worker gave up on, told in a heartbeat as a lease failure while the worker
// holds (and heartbeats) its next lease, is queued again at once: another worker gets its
// range without the clock moving (before, it waited for the lease timeout, postponed by the
// worker's heartbeats of its next lease).
// An undelivered report is a transport fault, not the job's: on the only known worker it
// does not fail the job (a render failure there would: ALeaseFailedOnTheOnlyWorkerFailsTheJob);
// the range goes back to the queue and the same worker renders it again. Reports that no
// server accepts still fail the job once ten distinct workers could not deliver one.
TEST_F(ManagerTest, AnUndeliveredReportOnTheOnlyWorkerDoesNotFailTheJob) {
    JobManager m(options);
    v1::Job job;
    ASSERT_TRUE(m.submit(request(m, 50), &job).ok());
    auto give_up = [&](const std::string& worker) {
        v1::LeaseRequest lr;
        lr.set_worker_id(worker);
        v1::LeaseReply lease;
        EXPECT_TRUE(m.lease(lr, &lease).ok());
        EXPECT_TRUE(lease.granted());
        v1::HeartbeatRequest hb;
        hb.set_worker_id(worker);
        v1::LeaseFailure* f = hb.add_failed_leases();
        f->set_lease_id(lease.lease().lease_id());
        f->set_error("the worker could not deliver its report: RESOURCE_EXHAUSTED");
        f->set_report_undelivered(true);
        v1::HeartbeatReply reply;
        EXPECT_TRUE(m.heartbeat(hb, &reply).ok());
        return lease;
    };
    const v1::LeaseReply first = give_up("w-1");
    ASSERT_TRUE(m.get(job.id(), &job).ok());
    EXPECT_NE(job.state(), v1::JOB_STATE_FAILED) << job.error();
    v1::LeaseRequest lr;
    lr.set_worker_id("w-1");
    v1::LeaseReply again;
    ASSERT_TRUE(m.lease(lr, &again).ok());
    ASSERT_TRUE(again.granted());
    EXPECT_EQ(again.lease().first_iteration(), first.lease().first_iteration());
    EXPECT_TRUE(render_and_report(m, again.lease()));  // a merge clears the count
    for (int w = 2; w <= 11; ++w) {
        ASSERT_TRUE(m.get(job.id(), &job).ok());
        ASSERT_NE(job.state(), v1::JOB_STATE_FAILED) << "after " << w - 2 << " workers";
        give_up("w-" + std::to_string(w));
    }
    ASSERT_TRUE(m.get(job.id(), &job).ok());
    EXPECT_EQ(job.state(), v1::JOB_STATE_FAILED);
    EXPECT_NE(job.error().find("RESOURCE_EXHAUSTED"), std::string::npos) << job.error();
}

TEST_F(ManagerTest, AReportGivenUpIsLeasedAgainAtOnce) {
    FakeClock clock;
    JobManager m(options, [&] { return clock.now; });
    v1::Job job;
    ASSERT_TRUE(m.submit(request(m, 50), &job).ok());
    // Two known workers: a lease failure on the only one would fail the job (the poison rule,
    // ALeaseFailedOnTheOnlyWorkerFailsTheJob).
    v1::RegisterWorkerReply one, two;
    m.register_worker({}, &one);
    m.register_worker({}, &two);
    const std::string w1 = one.worker_id(), w2 = two.worker_id();
    const v1::LeaseReply given_up = lease_for(m, w1);
    const v1::LeaseReply next = lease_for(m, w1);
    ASSERT_TRUE(given_up.granted());
    ASSERT_TRUE(next.granted());
    v1::HeartbeatRequest hb;
    hb.set_worker_id(w1);
    hb.add_lease_ids(next.lease().lease_id());
    v1::LeaseFailure* f = hb.add_failed_leases();
    f->set_lease_id(given_up.lease().lease_id());
    f->set_error("the worker could not deliver its report: INVALID_ARGUMENT");
    f->set_report_undelivered(true);
    v1::HeartbeatReply reply;
    ASSERT_TRUE(m.heartbeat(hb, &reply).ok());
    EXPECT_EQ(reply.cancelled_lease_ids_size(), 0);  // the next lease goes on
    const v1::LeaseReply again = lease_for(m, w2);
    ASSERT_TRUE(again.granted());
    EXPECT_EQ(again.lease().first_iteration(), given_up.lease().first_iteration());
    EXPECT_EQ(again.lease().end_iteration(), given_up.lease().end_iteration());
    // The given-up lease's report, should it arrive after all, is dropped (its lease is void).
    EXPECT_FALSE(render_and_report(m, given_up.lease()));
    EXPECT_TRUE(render_and_report(m, again.lease()));
    EXPECT_TRUE(render_and_report(m, next.lease()));
}
