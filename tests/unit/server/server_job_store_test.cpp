// The job store's two backends (server/job_store.h) against the same tests: SQLite in a
// temporary folder, PostgreSQL in a server of the test's own (postgres_instance.h; the cases
// skip, with the reason, where PostgreSQL is not installed).

#include <gtest/gtest.h>
#include <sqlite3.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <map>
#include <memory>
#include <set>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "server/job_store.h"
#include "server/store/open_job_store.h"
#include "server/store/sqlite_job_store.h"
#include "tests/support/temp_dir.h"
#include "tests/unit/server/postgres_instance.h"

using namespace render::server;
namespace fs = std::filesystem;

namespace {

class JobStoreTest : public ::testing::TestWithParam<std::string> {
  protected:
    void SetUp() override {
        if (postgres()) {
            pg_ = std::make_unique<render::testing::PostgresInstance>();
            if (!pg_->start_error().empty()) FAIL() << pg_->start_error();
            if (!pg_->skip_reason().empty()) GTEST_SKIP() << pg_->skip_reason();
        } else {
            const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
            std::string name = info->name();  // Test/param: one folder name
            std::replace(name.begin(), name.end(), '/', '_');
            dir_ = render::testing::fresh_temp_dir("server_job_store_test", name);
        }
    }
    void TearDown() override {
        if (!dir_.empty()) fs::remove_all(dir_);
    }
    bool postgres() const { return GetParam() == "postgresql"; }
    // The store's location as server --store takes it.
    std::string location() const {
        return postgres() ? pg_->url() : "sqlite:" + (dir_ / "render.db").string();
    }
    // A connection of its own to the store (as a second server's would be).
    std::unique_ptr<JobStore> open() const { return open_job_store(location()); }
    // `sql` run on the database outside the store.
    void raw(const std::string& sql) const {
        if (postgres()) {
            ASSERT_TRUE(pg_->psql(sql)) << sql;
            return;
        }
        sqlite3* db = nullptr;
        ASSERT_EQ(sqlite3_open((dir_ / "render.db").c_str(), &db), SQLITE_OK);
        char* error = nullptr;
        const int rc = sqlite3_exec(db, sql.c_str(), nullptr, nullptr, &error);
        const std::string message = error ? error : "";
        sqlite3_free(error);
        sqlite3_close(db);
        ASSERT_EQ(rc, SQLITE_OK) << sql << ": " << message;
    }

    std::unique_ptr<render::testing::PostgresInstance> pg_;
    fs::path dir_;
};

JobRow job_row(const std::string& id, int64_t sequence) {
    JobRow row;
    row.id = id;
    row.sequence = sequence;
    row.name = "name of " + id;
    row.request = std::string("\0binary\xff\x01", 9);  // a serialized proto: any bytes
    row.width = 4;
    row.height = 3;
    row.priority = 5;
    row.submitted_unix_ms = 1700000000123;
    return row;
}

LeaseRow lease(const std::string& id, const std::string& job, uint32_t frame, Range range) {
    return LeaseRow{id, "worker-" + id, job, frame, range};
}

}  // namespace

TEST_P(JobStoreTest, PersistsJobsFramesAndRangesAcrossReopening) {
    {
        auto store = open();
        store->insert_job(job_row("job-1", 7), 2);
        store->update_job_state("job-1", 2, "");
        store->add_merged_range("job-1", 1, {1, 5});
        store->update_frame("job-1", 0, true, 2.5);
        store->insert_lease("L1", "w", "job-1", 0, {5, 6});
    }
    auto store = open();
    auto jobs = store->load_jobs();
    ASSERT_EQ(jobs.size(), 1u);
    EXPECT_EQ(jobs[0].id, "job-1");
    EXPECT_EQ(jobs[0].request, std::string("\0binary\xff\x01", 9));
    EXPECT_EQ(jobs[0].name, "name of job-1");
    EXPECT_EQ(jobs[0].state, 2);
    EXPECT_EQ(jobs[0].priority, 5);
    EXPECT_EQ(jobs[0].width, 4);
    EXPECT_EQ(jobs[0].height, 3);
    EXPECT_EQ(jobs[0].submitted_unix_ms, 1700000000123);
    EXPECT_EQ(jobs[0].finished_unix_ms, 0);
    EXPECT_EQ(store->max_sequence(), 7);
    auto frames = store->load_frames("job-1");
    ASSERT_EQ(frames.size(), 2u);
    EXPECT_EQ(frames[0].index, 0u);
    EXPECT_TRUE(frames[0].done);
    EXPECT_DOUBLE_EQ(frames[0].elapsed_seconds, 2.5);
    EXPECT_EQ(frames[1].index, 1u);
    EXPECT_FALSE(frames[1].done);
    auto ranges = store->merged_ranges("job-1", 1);
    ASSERT_EQ(ranges.size(), 1u);
    EXPECT_EQ(ranges[0], (Range{1, 5}));
    auto leases = store->load_leases();
    ASSERT_EQ(leases.size(), 1u);
    EXPECT_EQ(leases[0].lease_id, "L1");
    EXPECT_EQ(leases[0].worker_id, "w");
    EXPECT_EQ(leases[0].range, (Range{5, 6}));
    const std::optional<LeaseRow> found = store->find_lease("L1");
    ASSERT_TRUE(found.has_value());
    EXPECT_EQ(found->job_id, "job-1");
    EXPECT_EQ(found->frame, leases[0].frame);
    EXPECT_EQ(found->range, (Range{5, 6}));
    EXPECT_FALSE(store->find_lease("L2").has_value());
    EXPECT_EQ(store->clear_leases(), 1);
    EXPECT_FALSE(store->find_lease("L1").has_value());
    EXPECT_EQ(store->clear_leases(), 0);
}

TEST_P(JobStoreTest, JobsLoadInSequenceOrderWithStateAndFinishTimes) {
    auto store = open();
    EXPECT_EQ(store->max_sequence(), 0);
    store->insert_job(job_row("b", 2), 1);
    store->insert_job(job_row("a", 1), 0);
    EXPECT_THROW(store->insert_job(job_row("a", 3), 1), std::runtime_error);  // id taken
    store->update_job_priority("b", -3);
    store->update_job_state("b", 4, "it broke", 1234);
    // A later state change without a finish time keeps the recorded one.
    store->update_job_state("b", 5, "cancelled", 0);
    auto jobs = store->load_jobs();
    ASSERT_EQ(jobs.size(), 2u);
    EXPECT_EQ(jobs[0].id, "a");
    EXPECT_EQ(jobs[1].id, "b");
    EXPECT_EQ(jobs[1].priority, -3);
    EXPECT_EQ(jobs[1].state, 5);
    EXPECT_EQ(jobs[1].error, "cancelled");
    EXPECT_EQ(jobs[1].finished_unix_ms, 1234);
    EXPECT_TRUE(store->load_frames("a").empty());
    EXPECT_EQ(store->max_sequence(), 2);
}

TEST_P(JobStoreTest, SaveFrameReplacesRangesAndDeleteJobRemovesEverything) {
    auto store = open();
    store->insert_job(job_row("j", 1), 2);
    store->insert_job(job_row("other", 2), 1);
    store->add_merged_range("j", 0, {1, 3});
    store->add_merged_range("j", 0, {7, 9});
    store->add_merged_range("other", 0, {1, 2});
    store->save_frame("j", 0, {{1, 5}, {6, 10}}, false, 1.5, 0);
    EXPECT_EQ(store->merged_ranges("j", 0), (std::vector<Range>{{1, 5}, {6, 10}}));
    store->set_merged_ranges("j", 0, {{1, 4}});
    EXPECT_EQ(store->merged_ranges("j", 0), (std::vector<Range>{{1, 4}}));
    store->save_frame("j", 1, {{1, 9}}, true, 3.0, 0);
    auto frames = store->load_frames("j");
    ASSERT_EQ(frames.size(), 2u);
    EXPECT_FALSE(frames[0].done);
    EXPECT_DOUBLE_EQ(frames[0].elapsed_seconds, 1.5);
    EXPECT_TRUE(frames[1].done);
    EXPECT_DOUBLE_EQ(frames[1].elapsed_seconds, 3.0);

    store->add_asset("aa", 10);
    store->add_asset("aa", 10);  // again: one row
    store->add_asset("bb", 20);
    store->insert_lease("L", "w", "j", 0, {4, 5});
    store->insert_lease("M", "w", "other", 0, {2, 3});
    store->delete_job("j", {"aa"});
    auto jobs = store->load_jobs();
    ASSERT_EQ(jobs.size(), 1u);
    EXPECT_EQ(jobs[0].id, "other");
    EXPECT_TRUE(store->load_frames("j").empty());
    EXPECT_TRUE(store->merged_ranges("j", 0).empty());
    EXPECT_EQ(store->merged_ranges("other", 0), (std::vector<Range>{{1, 2}}));
    auto leases = store->load_leases();
    ASSERT_EQ(leases.size(), 1u);
    EXPECT_EQ(leases[0].lease_id, "M");
    store->delete_lease("M");
    EXPECT_TRUE(store->load_leases().empty());
    // The asset rows: "aa" went with the job, "bb" with delete_assets.
    store->delete_assets({"bb"});
    store->add_asset("aa", 10);
    store->add_asset("bb", 20);
    store->delete_assets({"aa", "bb", "never-added"});
}

TEST_P(JobStoreTest, MigratesToTheCurrentSchemaAndRefusesANewerOne) {
    {
        auto store = open();
        EXPECT_EQ(store->schema_version(), kJobStoreSchemaVersion);
        store->insert_job(job_row("kept", 1), 1);
    }
    {
        auto store = open();  // an opened store is not migrated again
        EXPECT_EQ(store->schema_version(), kJobStoreSchemaVersion);
        EXPECT_EQ(store->load_jobs().size(), 1u);
    }
    raw("UPDATE schema_version SET version = " + std::to_string(kJobStoreSchemaVersion + 1));
    try {
        open();
        ADD_FAILURE() << "a store of a newer schema was opened";
    } catch (const std::runtime_error& e) {
        EXPECT_NE(std::string(e.what()).find("newer"), std::string::npos) << e.what();
    }
}

// Stores written before the schema was versioned (no schema_version table; with or without
// finished_ms) are migrated in place and keep their rows.
TEST_P(JobStoreTest, MigratesAStoreMadeBeforeVersions) {
    const std::string blob = postgres() ? "'\\x0102'::bytea" : "x'0102'";
    raw("CREATE TABLE jobs (id TEXT PRIMARY KEY, seq BIGINT NOT NULL, name TEXT, state INTEGER "
        "NOT NULL, priority INTEGER NOT NULL, request " +
        std::string(postgres() ? "BYTEA" : "BLOB") +
        " NOT NULL, width INTEGER, height INTEGER, error TEXT, submitted_ms BIGINT)");
    raw("INSERT INTO jobs VALUES ('old', 3, 'n', 2, 0, " + blob + ", 1, 1, '', 5)");
    auto store = open();
    EXPECT_EQ(store->schema_version(), kJobStoreSchemaVersion);
    auto jobs = store->load_jobs();
    ASSERT_EQ(jobs.size(), 1u);
    EXPECT_EQ(jobs[0].id, "old");
    EXPECT_EQ(jobs[0].request, std::string("\x01\x02"));
    EXPECT_EQ(jobs[0].finished_unix_ms, 0);  // the new column, NULL read as 0
    store->update_job_state("old", 4, "", 99);
    EXPECT_EQ(store->load_jobs()[0].finished_unix_ms, 99);
}

TEST_P(JobStoreTest, ClaimLeaseRefusesOverlapWithLeasesAndMergedRanges) {
    auto store = open();
    store->insert_job(job_row("j", 1), 2);
    store->save_frame("j", 0, {{1, 4}}, false, 0, 0);
    EXPECT_TRUE(store->claim_lease(lease("A", "j", 0, {4, 8})));
    EXPECT_FALSE(store->claim_lease(lease("B", "j", 0, {7, 9})));   // overlaps A
    EXPECT_FALSE(store->claim_lease(lease("C", "j", 0, {3, 4})));   // overlaps merged [1, 4)
    EXPECT_FALSE(store->claim_lease(lease("D", "j", 0, {2, 10})));  // covers both
    EXPECT_TRUE(store->claim_lease(lease("E", "j", 0, {8, 9})));    // adjacent to A
    EXPECT_TRUE(store->claim_lease(lease("F", "j", 1, {4, 8})));    // another frame
    EXPECT_FALSE(store->claim_lease(lease("G", "j", 2, {1, 2})));   // no such frame
    EXPECT_FALSE(store->claim_lease(lease("H", "x", 0, {1, 2})));   // no such job
    store->delete_lease("A");
    EXPECT_TRUE(store->claim_lease(lease("B", "j", 0, {5, 8})));  // A's range is free again
    std::set<std::string> ids;
    for (const LeaseRow& l : store->load_leases()) ids.insert(l.lease_id);
    EXPECT_EQ(ids, (std::set<std::string>{"B", "E", "F"}));
}

// Two stores on one database (as two servers) and several threads each claim every range of
// one frame: the database's locking lets exactly one claim of each range through. Without
// the lock in claim_lease two claims can both find no overlap and both insert.
TEST_P(JobStoreTest, ConcurrentClaimsFromTwoConnectionsNeverShareARange) {
    constexpr int kRanges = 40, kThreadsPerStore = 3;
    auto first = open();
    auto second = open();
    first->insert_job(job_row("j", 1), 1);
    std::atomic<int> granted{0};
    std::vector<std::thread> threads;
    for (int s = 0; s < 2; ++s)
        for (int t = 0; t < kThreadsPerStore; ++t)
            threads.emplace_back([&, s, t] {
                JobStore& store = s == 0 ? *first : *second;
                for (int k = 0; k < kRanges; ++k) {
                    // Ranges [2k+1, 2k+3) overlap their neighbours: of k and k+1 one at most.
                    const uint64_t begin = uint64_t(2 * k + 1);
                    std::string id = "s";  // built up: GCC 12 warns falsely on "literal" + chains
                    id += std::to_string(s);
                    id += "t";
                    id += std::to_string(t);
                    id += "k";
                    id += std::to_string(k);
                    if (store.claim_lease(lease(id, "j", 0, {begin, begin + 3}))) ++granted;
                }
            });
    for (std::thread& t : threads) t.join();
    std::vector<LeaseRow> leases = first->load_leases();
    EXPECT_EQ(int(leases.size()), granted.load());
    EXPECT_GT(granted.load(), 0);
    for (size_t i = 1; i < leases.size(); ++i)  // sorted by first
        EXPECT_LE(leases[i - 1].range.end, leases[i].range.first)
            << leases[i - 1].lease_id << " and " << leases[i].lease_id << " overlap";
}

// A job's hold (several servers on one store, docs/design/job-store.md): taken by one server
// at a time, renewed only by the epoch that took it, free again once it runs out (on the
// database's clock) or is given up, and every new holder gets a new epoch.
TEST_P(JobStoreTest, AHoldIsTakenOnceRenewedByItsEpochAndFreedByTimeOrRelease) {
    auto a = open();
    auto b = open();
    a->insert_job(job_row("j", 1), 1);
    EXPECT_EQ(a->load_jobs()[0].owner.server, "");
    EXPECT_FALSE(a->load_jobs()[0].owner.live);
    const std::optional<int64_t> first = a->take_job("j", "A", "a:1", 60000);
    ASSERT_TRUE(first.has_value());
    EXPECT_FALSE(b->take_job("j", "B", "b:1", 60000).has_value());  // A holds it
    EXPECT_TRUE(a->renew_job("j", "A", *first, 60000));
    EXPECT_FALSE(b->renew_job("j", "B", *first, 60000));  // not B's
    JobRow row = b->load_jobs()[0];
    EXPECT_EQ(row.owner.server, "A");
    EXPECT_EQ(row.owner.address, "a:1");
    EXPECT_EQ(row.owner.epoch, *first);
    EXPECT_TRUE(row.owner.live);

    // A hold of 1 ms has run out 50 ms later: B takes the job, and A's epoch is over.
    ASSERT_TRUE(a->renew_job("j", "A", *first, 1));
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    EXPECT_FALSE(a->load_jobs()[0].owner.live);
    const std::optional<int64_t> second = b->take_job("j", "B", "b:1", 60000);
    ASSERT_TRUE(second.has_value());
    EXPECT_GT(*second, *first);
    EXPECT_FALSE(a->renew_job("j", "A", *first, 60000));  // taken since: A must drop the job

    b->release_job("j", "A", *first);  // not the holder: nothing happens
    EXPECT_TRUE(a->load_jobs()[0].owner.live);
    b->release_job("j", "B", *second);
    EXPECT_FALSE(a->load_jobs()[0].owner.live);
    const std::optional<int64_t> third = a->take_job("j", "A", "a:1", 60000);
    ASSERT_TRUE(third.has_value());
    EXPECT_GT(*third, *second);
}

// The write fence (docs/design/job-store.md, "The write fence"): a frame's ranges are written
// with a hold's epoch only while the job is held in that epoch; a holder whose hold was taken
// (or released) writes nothing, and the new holder's ranges stay.
TEST_P(JobStoreTest, AFencedSaveFrameWritesOnlyInTheCurrentHold) {
    auto a = open();
    auto b = open();
    a->insert_job(job_row("j", 1), 1);
    EXPECT_THROW(a->save_frame("j", 0, {{1, 3}}, false, 1, 1), HoldLost);  // never held
    const std::optional<int64_t> first = a->take_job("j", "A", "a:1", 1);
    ASSERT_TRUE(first.has_value());
    a->save_frame("j", 0, {{1, 3}}, false, 1, *first);
    EXPECT_EQ(b->merged_ranges("j", 0), (std::vector<Range>{{1, 3}}));
    std::this_thread::sleep_for(std::chrono::milliseconds(50));  // A's hold of 1 ms ran out
    const std::optional<int64_t> second = b->take_job("j", "B", "b:1", 60000);
    ASSERT_TRUE(second.has_value());
    b->save_frame("j", 0, {{1, 5}}, false, 2, *second);
    EXPECT_THROW(a->save_frame("j", 0, {{1, 9}}, true, 3, *first), HoldLost);
    EXPECT_EQ(a->merged_ranges("j", 0), (std::vector<Range>{{1, 5}}));
    EXPECT_FALSE(a->load_frames("j")[0].done);
    b->release_job("j", "B", *second);
    EXPECT_THROW(b->save_frame("j", 0, {{1, 9}}, true, 3, *second), HoldLost);  // released
    a->save_frame("j", 0, {{1, 9}}, true, 3, 0);  // unfenced (one server): written
    EXPECT_EQ(a->merged_ranges("j", 0), (std::vector<Range>{{1, 9}}));
}

// Servers taking one job at once through their own connections: exactly one gets it.
TEST_P(JobStoreTest, OfServersTakingAJobAtOnceExactlyOneGetsIt) {
    constexpr int kJobs = 20;
    auto a = open();
    auto b = open();
    for (int j = 0; j < kJobs; ++j) a->insert_job(job_row("j" + std::to_string(j), j + 1), 1);
    std::atomic<int> taken[2] = {0, 0};
    std::vector<std::thread> threads;
    for (int s = 0; s < 2; ++s)
        threads.emplace_back([&, s] {
            JobStore& store = s == 0 ? *a : *b;
            for (int j = 0; j < kJobs; ++j)
                if (store.take_job("j" + std::to_string(j), s == 0 ? "A" : "B", "x:1", 60000))
                    ++taken[s];
        });
    for (std::thread& t : threads) t.join();
    EXPECT_EQ(taken[0] + taken[1], kJobs);
    int held_by_a = 0;
    for (const JobRow& row : a->load_jobs()) {
        EXPECT_TRUE(row.owner.live) << row.id;
        EXPECT_EQ(row.owner.epoch, 1) << row.id;  // taken once, never taken again
        held_by_a += row.owner.server == "A";
    }
    EXPECT_EQ(held_by_a, taken[0].load());
}

// A new holder voids its predecessor's leases of the job, and only that job's.
TEST_P(JobStoreTest, ClearJobLeasesVoidsOneJobsLeases) {
    auto store = open();
    store->insert_job(job_row("j", 1), 1);
    store->insert_job(job_row("k", 2), 1);
    EXPECT_TRUE(store->claim_lease(lease("A", "j", 0, {1, 3})));
    EXPECT_TRUE(store->claim_lease(lease("B", "k", 0, {1, 3})));
    EXPECT_EQ(store->clear_job_leases("j"), 1);
    std::vector<LeaseRow> left = store->load_leases();
    ASSERT_EQ(left.size(), 1u);
    EXPECT_EQ(left[0].lease_id, "B");
    EXPECT_TRUE(store->claim_lease(lease("C", "j", 0, {1, 3})));  // the range is free again
}

// The rows of reported leases go in one batch (JobManager::delete_reported_leases): the named
// ones only, ids of rows already gone are passed over, and an id with a quote or a backslash
// is one id (PostgreSQL receives them as one array literal).
TEST_P(JobStoreTest, DeleteLeasesRemovesTheNamedRowsInOneBatch) {
    auto store = open();
    store->insert_job(job_row("j", 1), 1);
    for (const char* id : {"A", "B", "C\\\"D", "E"}) store->insert_lease(id, "w", "j", 0, {1, 2});
    store->delete_leases({});
    EXPECT_EQ(store->load_leases().size(), 4u);
    store->delete_leases({"A", "C\\\"D", "gone"});
    std::set<std::string> ids;
    for (const LeaseRow& l : store->load_leases()) ids.insert(l.lease_id);
    EXPECT_EQ(ids, (std::set<std::string>{"B", "E"}));
}

// The database restarting under a running server (a failover, an upgrade): the operation that
// finds the connection broken fails (the server logs it, as any failed write), and the next
// ones reconnect, the Lease path's prepared statements included. PostgreSQL only: SQLite has
// no server to lose.
TEST_P(JobStoreTest, ReconnectsAfterTheDatabaseRestarts) {
    if (!postgres()) GTEST_SKIP() << "SQLite is embedded: no database server to restart";
    auto store = open();
    store->insert_job(job_row("j", 1), 1);
    store->insert_lease("before", "w", "j", 0, {1, 2});
    ASSERT_TRUE(pg_->restart());
    int failures = 0;
    std::vector<JobRow> jobs;
    for (int attempt = 0; attempt < 3 && jobs.empty(); ++attempt) {
        try {
            jobs = store->load_jobs();
        } catch (const std::runtime_error& e) {
            std::printf("attempt %d: %s\n", attempt, e.what());
            ++failures;
        }
    }
    ASSERT_EQ(jobs.size(), 1u) << failures << " failed attempts";
    EXPECT_LE(failures, 1);  // the one that found the connection broken
    store->insert_lease("after", "w", "j", 0, {2, 3});
    store->delete_lease("before");
    auto leases = store->load_leases();
    ASSERT_EQ(leases.size(), 1u);
    EXPECT_EQ(leases[0].lease_id, "after");
}

// The farm's workers (docs/design/job-store.md, "The farm's workers"): a server that stops
// syncing (dead) is no longer listed once its rows are older than the
// reader's limit, and a live server's departed worker leaves the farm at its next sync.
TEST_P(JobStoreTest, TheFarmsWorkersForgetDeadServers) {
    auto store = open();
    FarmWorkerRow w;
    w.worker_id = "w-1";
    w.host = "render-07";
    w.threads = 16;
    w.server_address = "a:1";
    store->record_workers("s-a", {w}, 60000);
    w.worker_id = "w-2";
    w.server_address = "b:2";
    store->record_workers("s-b", {w}, 60000);
    std::vector<FarmWorkerRow> all = store->load_workers(60000);
    ASSERT_EQ(all.size(), 2u);
    EXPECT_EQ(all[0].server, "s-a");
    EXPECT_EQ(all[0].host, "render-07");
    EXPECT_EQ(all[0].threads, 16u);
    EXPECT_EQ(all[1].worker_id, "w-2");
    store->record_workers("s-a", {}, 60000);  // A's worker left
    all = store->load_workers(60000);
    ASSERT_EQ(all.size(), 1u);
    EXPECT_EQ(all[0].server, "s-b");
    raw("UPDATE farm_workers SET recorded_ms = recorded_ms - 5000");
    EXPECT_TRUE(store->load_workers(4000).empty());  // B silent for longer than that
    EXPECT_EQ(store->load_workers(60000).size(), 1u);
    store->record_workers("s-a", {}, 1000);  // anyone's rows older than 1 s are removed
    EXPECT_TRUE(store->load_workers(60000).empty());
}

TEST(JobStoreLocation, UrlsPickTheBackendAndHidePasswords) {
    EXPECT_TRUE(is_store_url("postgresql://u@h/db"));
    EXPECT_TRUE(is_store_url("postgres://h/db"));
    EXPECT_TRUE(is_store_url("sqlite:/srv/render.db"));
    EXPECT_FALSE(is_store_url("/srv/render"));
    EXPECT_FALSE(is_store_url("store"));
    EXPECT_EQ(sqlite_url_path("sqlite:/srv/render.db"), "/srv/render.db");
    EXPECT_EQ(sqlite_url_path("sqlite:///srv/render.db"), "/srv/render.db");
    EXPECT_EQ(sqlite_url_path("sqlite:rel.db"), "rel.db");
    EXPECT_EQ(sqlite_url_path("/srv"), "");
    EXPECT_THROW(open_job_store("/srv/render"), std::invalid_argument);
    EXPECT_THROW(open_job_store("sqlite:"), std::invalid_argument);
    EXPECT_EQ(redact_store_url("postgresql://render:s3cret@db:5432/render"),
              "postgresql://render:***@db:5432/render");
    EXPECT_EQ(redact_store_url("postgresql://db/render?user=r&password=s3cret&sslmode=require"),
              "postgresql://db/render?user=r&password=***&sslmode=require");
    EXPECT_EQ(redact_store_url("postgresql://render@db/render"), "postgresql://render@db/render");
}

INSTANTIATE_TEST_SUITE_P(Backends, JobStoreTest, ::testing::Values("sqlite", "postgresql"),
                         [](const ::testing::TestParamInfo<std::string>& info) {
                             return info.param;
                         });
