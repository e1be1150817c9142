// Two job managers on one PostgreSQL store and one data folder, as two servers of one farm
// (docs/design/job-store.md, "Several servers, one farm"): a job's sums are held by one server
// at a time, any server answers for any job, and a holder that dies or lapses is taken over
// from its last checkpoint without a range merged twice. Skipped, with the reason, where
// PostgreSQL is not installed.

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <filesystem>
#include <memory>
#include <thread>

#include "core/image/exr_io.h"
#include "core/render/render_iterations.h"
#include "core/scene/loader/scene_loader.h"
#include "core/util/sha256.h"
#include "server/frame_files.h"
#include "server/job_manager.h"
#include "server/store/open_job_store.h"
#include "tests/support/server_test_scene.h"
#include "tests/support/temp_dir.h"
#include "tests/unit/server/postgres_instance.h"

using namespace render;
using namespace render::server;
namespace fs = std::filesystem;
namespace v1 = render::v1;

namespace {

const char* kScene = render::testing::kServerTestScene;

// A clock a test moves forward (to make a checkpoint due without waiting).
struct TestClock {
    std::shared_ptr<std::atomic<int64_t>> offset_s = std::make_shared<std::atomic<int64_t>>(0);
    Scheduler::ClockFn fn() const {
        return [o = offset_s] { return SteadyClock::now() + std::chrono::seconds(o->load()); };
    }
};

class SharedStoreTest : public ::testing::Test {
  protected:
    void SetUp() override {
        pg_ = std::make_unique<render::testing::PostgresInstance>();
        if (!pg_->start_error().empty()) FAIL() << pg_->start_error();
        if (!pg_->skip_reason().empty()) GTEST_SKIP() << pg_->skip_reason();
        dir_ = render::testing::fresh_temp_dir(
            "server_shared_store_test",
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    }
    void TearDown() override {
        if (!dir_.empty()) fs::remove_all(dir_);
    }

    ServerOptions options(const fs::path& data, double checkpoint_seconds) const {
        ServerOptions o;
        o.store = data;
        o.database = pg_->url();
        o.hold_seconds = 0.4;  // renewed every 0.1 s by tick()
        o.checkpoint_seconds = checkpoint_seconds;
        o.lease_timeout_seconds = 30;
        return o;
    }

    static v1::SubmitJobRequest request(JobManager& m, uint64_t iterations) {
        const std::string data = kScene;
        const std::string sha = sha256_hex(data);
        AssetStore::Upload u(m.assets(), sha, data.size());
        EXPECT_EQ(u.write(data), "");
        EXPECT_EQ(u.commit(), "");
        v1::SubmitJobRequest r;
        r.set_name("shared");
        r.mutable_settings()->set_algorithm("pt");
        r.mutable_settings()->set_iterations(iterations);
        r.mutable_bundle()->set_scene_path("scene.xml");
        v1::BundleFile* f = r.mutable_bundle()->add_files();
        f->set_path("scene.xml");
        f->set_sha256(sha);
        f->set_size(data.size());
        return r;
    }

    static std::string register_worker(JobManager& m) {
        v1::RegisterWorkerReply reply;
        m.register_worker({}, &reply);
        return reply.worker_id();
    }

    static v1::LeaseReply lease(JobManager& m, const std::string& worker) {
        v1::LeaseRequest request;
        request.set_worker_id(worker);
        v1::LeaseReply reply;
        EXPECT_TRUE(m.lease(request, &reply).ok());
        return reply;
    }

    // Renders the lease as a worker would and reports it; whether it was merged. A long
    // `render_seconds` keeps the worker's next leases at one iteration (its measured rate).
    static bool render_and_report(JobManager& m, const v1::Lease& lease,
                                  double render_seconds = 0.01) {
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
        ReportValues values = ReportValues::in_memory(2 * n);
        for (const auto* part : {&r.sum.values(), &r.odd_sum.values()})
            EXPECT_EQ(values.append({reinterpret_cast<const char*>(part->data()),
                                     part->size() * sizeof(double)}),
                      "");
        bool merged = false;
        EXPECT_TRUE(m.report(h, std::move(values), &merged).ok());
        return merged;
    }

    // Ticks `m` until it holds `job_id` (bounded: a hold runs out in 0.4 s).
    static bool wait_until_held(JobManager& m, const std::string& job_id) {
        for (int i = 0; i < 400; ++i) {
            m.tick();
            for (const std::string& id : m.held_jobs())
                if (id == job_id) return true;
            std::this_thread::sleep_for(std::chrono::milliseconds(10));
        }
        return false;
    }

    // Leases and reports on `m` until the job is done; returns the ranges merged.
    static std::vector<Range> render_to_the_end(JobManager& m, const std::string& worker,
                                                const std::string& job_id) {
        std::vector<Range> merged;
        for (int i = 0; i < 400; ++i) {
            v1::Job job;
            EXPECT_TRUE(m.get(job_id, &job).ok());
            if (job.state() == v1::JOB_STATE_DONE) break;
            v1::LeaseReply reply = lease(m, worker);
            if (!reply.granted()) {
                m.tick();
                std::this_thread::sleep_for(std::chrono::milliseconds(10));
                continue;
            }
            if (render_and_report(m, reply.lease()))
                merged.push_back({reply.lease().first_iteration(), reply.lease().end_iteration()});
        }
        return merged;
    }

    // The image one server on SQLite makes of the same job: the iteration contract makes the
    // image independent of how its range was cut into leases and which server merged them.
    Image reference(uint64_t iterations) {
        ServerOptions o;
        o.store = dir_ / "reference";
        JobManager m(o);
        v1::Job job;
        EXPECT_TRUE(m.submit(request(m, iterations), &job).ok());
        const std::string worker = register_worker(m);
        render_to_the_end(m, worker, job.id());
        return read_image(m.options().store / "results" / job.id() / "0.exr");
    }

    static Image result(JobManager& m, const std::string& job_id) {
        v1::FetchResultRequest request;
        request.set_job_id(job_id);
        fs::path file;
        bool temporary = false;
        EXPECT_TRUE(m.result_file(request, &file, &temporary).ok());
        return read_image(file);
    }

    static void expect_same_pixels(const Image& a, const Image& b) {
        ASSERT_EQ(a.width(), b.width());
        ASSERT_EQ(a.height(), b.height());
        for (size_t i = 0; i < a.pixel_count() * 3; ++i)
            ASSERT_EQ(a.data()[i], b.data()[i]) << "value " << i;
    }

    std::unique_ptr<render::testing::PostgresInstance> pg_;
    fs::path dir_;
};

}  // namespace

// A job submitted to one server is seen at once by the other; the two servers spread two
// jobs between them, lease them at once from two threads, and each job's ranges are leased
// once, merged once, and give the one-server image; the server that did not hold a job
// serves its finished frame from the shared folder.
TEST_F(SharedStoreTest, TwoServersShareTheJobsAndEachRangeIsMergedOnce) {
    constexpr uint64_t kIterations = 12;
    const Image expected = reference(kIterations);
    JobManager a(options(dir_ / "data", 0));
    JobManager b(options(dir_ / "data", 0));
    const std::string wa = register_worker(a), wb = register_worker(b);
    v1::Job first, second;
    ASSERT_TRUE(a.submit(request(a, kIterations), &first).ok());
    ASSERT_TRUE(b.submit(request(b, kIterations), &second).ok());
    v1::Job seen;
    ASSERT_TRUE(b.get(first.id(), &seen).ok());  // submitted through A, asked of B
    EXPECT_EQ(seen.id(), first.id());

    // Each server takes one job (it holds no more than the other).
    for (int i = 0; i < 400 && a.held_jobs().size() + b.held_jobs().size() < 2; ++i) {
        a.tick();
        b.tick();
        std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    ASSERT_EQ(a.held_jobs().size(), 1u);
    ASSERT_EQ(b.held_jobs().size(), 1u);
    EXPECT_NE(a.held_jobs()[0], b.held_jobs()[0]);

    std::vector<Range> on_a, on_b;
    std::thread ta([&] { on_a = render_to_the_end(a, wa, a.held_jobs()[0]); });
    std::thread tb([&] { on_b = render_to_the_end(b, wb, b.held_jobs().at(0)); });
    ta.join();
    tb.join();
    for (std::vector<Range>* ranges : {&on_a, &on_b}) {
        IntervalSet all;
        uint64_t total = 0;
        for (const Range& r : *ranges) {
            EXPECT_FALSE(all.overlaps(r)) << r.first << ".." << r.end << " merged twice";
            all.add(r);
            total += r.size();
        }
        EXPECT_EQ(total, kIterations);
        EXPECT_EQ(all.ranges(), (std::vector<Range>{{1, kIterations + 1}}));
    }
    for (int i = 0; i < 3; ++i) {  // the other server reads the jobs' end from the store
        a.tick();
        b.tick();
        std::this_thread::sleep_for(std::chrono::milliseconds(120));
    }
    for (JobManager* m : {&a, &b})
        for (const std::string& id : {first.id(), second.id()}) {
            v1::Job job;
            ASSERT_TRUE(m->get(id, &job).ok());
            EXPECT_EQ(job.state(), v1::JOB_STATE_DONE) << id;
            expect_same_pixels(result(*m, id), expected);
        }
}

// The holder dies (its manager destroyed without a checkpoint at shutdown) with one report
// merged after its last checkpoint and one lease outstanding: the other server takes the job
// once the hold runs out, starts from the checkpoint, drops the dead holder's late reports,
// leases both ranges again, and the image is the one-server image: nothing merged twice.
TEST_F(SharedStoreTest, ADeadHoldersJobIsTakenOverFromItsLastCheckpoint) {
    constexpr uint64_t kIterations = 8;
    const Image expected = reference(kIterations);
    TestClock clock;
    auto a = std::make_unique<JobManager>(options(dir_ / "data", 1000), clock.fn());
    const std::string wa = register_worker(*a);
    v1::Job job;
    ASSERT_TRUE(a->submit(request(*a, kIterations), &job).ok());
    ASSERT_TRUE(wait_until_held(*a, job.id()));
    v1::LeaseReply l1 = lease(*a, wa);
    ASSERT_TRUE(l1.granted());
    ASSERT_TRUE(render_and_report(*a, l1.lease(), 100));
    clock.offset_s->fetch_add(2000);  // the checkpoint is due
    a->tick();
    const uint64_t checkpointed = l1.lease().end_iteration() - l1.lease().first_iteration();
    v1::LeaseReply l2 = lease(*a, wa);
    ASSERT_TRUE(l2.granted());
    ASSERT_TRUE(render_and_report(*a, l2.lease(), 100));  // merged after the checkpoint
    v1::LeaseReply l3 = lease(*a, wa);
    ASSERT_TRUE(l3.granted());  // outstanding when A dies
    a.reset();

    JobManager b(options(dir_ / "data", 0));
    const std::string wb = register_worker(b);
    ASSERT_TRUE(wait_until_held(b, job.id()));
    v1::Job seen;
    ASSERT_TRUE(b.get(job.id(), &seen).ok());
    EXPECT_EQ(seen.frames(0).iterations_done(), checkpointed);
    EXPECT_FALSE(render_and_report(b, l2.lease()));  // the dead holder's leases are void
    EXPECT_FALSE(render_and_report(b, l3.lease()));
    const std::vector<Range> merged = render_to_the_end(b, wb, job.id());
    uint64_t total = checkpointed;
    for (const Range& r : merged) total += r.size();
    EXPECT_EQ(total, kIterations);
    ASSERT_TRUE(b.get(job.id(), &seen).ok());
    EXPECT_EQ(seen.state(), v1::JOB_STATE_DONE);
    EXPECT_EQ(seen.frames(0).iterations_done(), kIterations);
    expect_same_pixels(result(b, job.id()), expected);
}

// A dead server's jobs are all taken in the one sync that finds their holds run out, not one
// per sync: each sync waits a quarter of the hold, so with one job a sync their leases would
// stay lost a quarter of a hold longer for every job the dead server held
// (docs/design/job-store.md, "What each server does").
TEST_F(SharedStoreTest, ADeadServersJobsAreAllTakenInOneSync) {
    auto a = std::make_unique<JobManager>(options(dir_ / "data", 0));
    register_worker(*a);
    v1::Job first, second;
    ASSERT_TRUE(a->submit(request(*a, 4), &first).ok());
    ASSERT_TRUE(a->submit(request(*a, 4), &second).ok());
    // New jobs are taken one per sync (servers starting together spread them).
    ASSERT_TRUE(wait_until_held(*a, first.id()));
    ASSERT_TRUE(wait_until_held(*a, second.id()));
    ASSERT_EQ(a->held_jobs().size(), 2u);
    a.reset();  // dies holding both (no release)

    JobManager b(options(dir_ / "data", 0));
    register_worker(b);
    ASSERT_TRUE(wait_until_held(b, first.id()));
    EXPECT_EQ(b.held_jobs().size(), 2u) << "the second job was left for a later sync";
}

// A lease that expired is handed out again at the next ask: the Lease that expires it deletes
// its row before claiming the range again (the store would refuse the claim over the expired
// lease's row, and the worker would wait an idle pause with the range queued).
TEST_F(SharedStoreTest, AnExpiredRangeIsLeasedAgainAtTheNextAsk) {
    TestClock clock;
    JobManager a(options(dir_ / "data", 0), clock.fn());
    const std::string w1 = register_worker(a), w2 = register_worker(a);
    v1::Job job;
    ASSERT_TRUE(a.submit(request(a, 8), &job).ok());
    ASSERT_TRUE(wait_until_held(a, job.id()));
    const v1::LeaseReply first = lease(a, w1);
    ASSERT_TRUE(first.granted());
    clock.offset_s->fetch_add(60);  // past the lease timeout (30 s): w1 never heartbeated
    const v1::LeaseReply again = lease(a, w2);
    ASSERT_TRUE(again.granted()) << "the store refused the expired range";
    EXPECT_EQ(again.lease().first_iteration(), first.lease().first_iteration());
}

// A holder that stopped renewing (stalled, cut off from the database) finds its hold taken:
// it drops the job, its workers' leases are cancelled and their reports are not merged.
TEST_F(SharedStoreTest, AServerWhoseHoldWasTakenStopsMergingTheJob) {
    JobManager a(options(dir_ / "data", 0));
    const std::string wa = register_worker(a);
    v1::Job job;
    ASSERT_TRUE(a.submit(request(a, 8), &job).ok());
    ASSERT_TRUE(wait_until_held(a, job.id()));
    v1::LeaseReply stale = lease(a, wa);
    ASSERT_TRUE(stale.granted());

    JobManager b(options(dir_ / "data", 0));
    register_worker(b);
    ASSERT_TRUE(wait_until_held(b, job.id()));  // A did not renew meanwhile
    a.tick();                                   // A's renewal fails: it gives the job up
    EXPECT_TRUE(a.held_jobs().empty());
    v1::HeartbeatRequest hb;
    hb.set_worker_id(wa);
    hb.add_lease_ids(stale.lease().lease_id());
    v1::HeartbeatReply cancelled;
    ASSERT_TRUE(a.heartbeat(hb, &cancelled).ok());
    ASSERT_EQ(cancelled.cancelled_lease_ids_size(), 1);
    EXPECT_FALSE(render_and_report(a, stale.lease()));
    EXPECT_FALSE(lease(a, wa).granted());  // A no longer leases the job
}

// The write fence (docs/design/job-store.md, "The write fence"): a holder that lost its hold
// while a checkpoint was on its way (it renewed, then stalled past its hold) writes only its
// own epoch's file, which the store refuses to record; the new holder's checkpoint and ranges
// stay, and a later holder loads the new holder's checkpoint, not the lapsed one's.
TEST_F(SharedStoreTest, ALapsedHoldersCheckpointNeverReplacesTheNewHolders) {
    const fs::path data = dir_ / "data";
    JobManager m(options(data, 1000));  // submits the job; no worker, so it never holds it
    v1::Job job;
    ASSERT_TRUE(m.submit(request(m, 16), &job).ok());
    auto store_a = open_job_store(pg_->url());
    auto store_b = open_job_store(pg_->url());
    FrameFiles files_a(data, *store_a, SteadyClock::now, 0);
    FrameFiles files_b(data, *store_b, SteadyClock::now, 0);
    // Sums of one value per range, so that whose sums a checkpoint holds is plain.
    auto add = [](FrameData& frame, Range r, double value) {
        if (!frame.acc) frame.acc = std::make_unique<FrameAccumulator>(8, 6);
        const std::vector<double> sum(frame.acc->value_count(), value * double(r.size()));
        const std::vector<double> odd(frame.acc->value_count(), 0.0);
        frame.acc->add(r, sum, odd, {}, r.end / 2 - r.first / 2, RenderStats{});
    };
    const std::optional<int64_t> ea = store_a->take_job(job.id(), "A", "a:1", 1);
    ASSERT_TRUE(ea.has_value());
    FrameData a;
    a.hold_epoch = *ea;
    add(a, {1, 3}, 1.0);
    ASSERT_TRUE(files_a.save_checkpoint(job.id(), 0, a, 1, "test"));

    std::this_thread::sleep_for(std::chrono::milliseconds(50));  // A's 1-ms hold ran out
    const std::optional<int64_t> eb = store_b->take_job(job.id(), "B", "b:1", 60000);
    ASSERT_TRUE(eb.has_value());
    FrameData b;
    b.hold_epoch = *eb;
    FramePlan plan;
    ASSERT_TRUE(files_b.load_checkpoint(job.id(), 0, 8, 6, RenderSettings{}, b, plan));
    EXPECT_EQ(plan.merged.ranges(), (std::vector<Range>{{1, 3}}));
    add(b, {3, 5}, 2.0);
    ASSERT_TRUE(files_b.save_checkpoint(job.id(), 0, b, 2, "test"));
    EXPECT_FALSE(fs::exists(files_a.checkpoint_path(job.id(), 0, *ea)));  // superseded

    // A, lapsed, merges the range B merged and writes: its file only, and the store refuses.
    add(a, {3, 5}, 100.0);
    EXPECT_FALSE(files_a.save_checkpoint(job.id(), 0, a, 3, "test"));
    EXPECT_EQ(store_b->merged_ranges(job.id(), 0), (std::vector<Range>{{1, 5}}));
    EXPECT_TRUE(fs::exists(files_b.checkpoint_path(job.id(), 0, *eb)));

    // The next holder loads B's checkpoint: B's sums, never A's late ones.
    store_b->release_job(job.id(), "B", *eb);
    const std::optional<int64_t> ec = store_a->take_job(job.id(), "C", "c:1", 60000);
    ASSERT_TRUE(ec.has_value());
    FrameData c;
    c.hold_epoch = *ec;
    FramePlan plan_c;
    ASSERT_TRUE(files_a.load_checkpoint(job.id(), 0, 8, 6, RenderSettings{}, c, plan_c));
    EXPECT_EQ(plan_c.merged.ranges(), (std::vector<Range>{{1, 5}}));
    ASSERT_TRUE(c.acc);
    EXPECT_EQ(c.acc->count(), 4u);
    // Sum over [1, 5): 2 iterations of 1.0 (A's, before it lapsed) and 2 of 2.0 (B's).
    EXPECT_DOUBLE_EQ(c.acc->average().data()[0], (2 * 1.0 + 2 * 2.0) / 4);
}

// The jobs spread over the servers that have workers, a server holding none included
// (docs/design/job-store.md, "Spreading the jobs"): A syncs twice before B takes anything,
// yet takes only one of two jobs, because B has recorded a live worker and holds fewer; B
// then takes the other. Every server's /api/farm lists both servers' workers.
TEST_F(SharedStoreTest, JobsSpreadOverServersWithWorkersAndEachListsTheFarmsWorkers) {
    ServerOptions oa = options(dir_ / "data", 0), ob = oa;
    oa.hold_seconds = ob.hold_seconds = 8;  // synced every 2 s; a worker row counts for 4 s
    oa.advertise_address = "a.example:1";
    ob.advertise_address = "b.example:2";
    JobManager a(oa);
    JobManager b(ob);
    const std::string wa = register_worker(a), wb = register_worker(b);
    b.tick();  // B records its worker; there is no job to take yet
    v1::Job first, second;
    ASSERT_TRUE(a.submit(request(a, 4), &first).ok());
    ASSERT_TRUE(a.submit(request(a, 4), &second).ok());
    const auto sync_interval = std::chrono::milliseconds(2100);
    a.tick();
    std::this_thread::sleep_for(sync_interval);
    a.tick();
    EXPECT_EQ(a.held_jobs().size(), 1u)
        << "A took a second job while B, with a worker, held none: " << a.farm_json();
    std::this_thread::sleep_for(sync_interval);
    b.tick();
    ASSERT_EQ(b.held_jobs().size(), 1u);
    ASSERT_EQ(a.held_jobs().size(), 1u);
    EXPECT_NE(a.held_jobs()[0], b.held_jobs()[0]);

    std::this_thread::sleep_for(sync_interval);
    a.tick();
    b.tick();
    for (JobManager* m : {&a, &b}) {
        const std::string farm = m->farm_json();
        for (const auto& [worker, server] :
             {std::pair{wa, oa.advertise_address}, std::pair{wb, ob.advertise_address}})
            EXPECT_NE(farm.find("{\"worker_id\":\"" + worker + "\",\"server\":\"" + server + "\""),
                      std::string::npos)
                << worker << " on " << server << " missing from " << farm;
    }
    EXPECT_NE(a.farm_json().find("\"worker_id\":\"" + wa +
                                 "\",\"server\":\"a.example:1\","
                                 "\"self\":true"),
              std::string::npos);
    EXPECT_NE(a.farm_json().find("\"worker_id\":\"" + wb +
                                 "\",\"server\":\"b.example:2\","
                                 "\"self\":false"),
              std::string::npos);
}
