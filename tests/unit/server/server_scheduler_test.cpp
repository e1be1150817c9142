// The server's lease table and iteration bookkeeping: exactly-once merges, expired lease
// requeue, priority order, range sizing. Time is injected; nothing sleeps.

#include <gtest/gtest.h>

#include "server/interval_set.h"
#include "server/scheduler.h"

using namespace render::server;

namespace {

struct FakeClock {
    TimePoint now = TimePoint{} + std::chrono::hours(1);
    void advance(double seconds) {
        now += std::chrono::duration_cast<SteadyClock::duration>(
            std::chrono::duration<double>(seconds));
    }
};

std::vector<FramePlan> frames(int n, uint64_t target, double budget = 0) {
    std::vector<FramePlan> out(n);
    for (FramePlan& f : out) {
        f.target = target;
        f.budget_seconds = budget;
    }
    return out;
}

struct SchedulerTest : ::testing::Test {
    FakeClock clock;
    Scheduler scheduler{SchedulerOptions{10, 3}, [this] { return clock.now; }};

    // Leases, merges and finishes everything the worker gets until nothing is left.
    uint64_t drain(const std::string& worker) {
        uint64_t merged = 0;
        while (auto g = scheduler.lease(worker)) {
            LeaseGrant out;
            EXPECT_EQ(scheduler.begin_merge(g->lease_id, 1.0, &out), MergeDecision::Accept);
            scheduler.end_merge(out);
            merged += g->range.size();
            for (auto [job, frame] : scheduler.tick()) scheduler.finish_frame(job, frame);
        }
        return merged;
    }
};

}  // namespace

TEST(IntervalSet, AddJoinsAndSubtractSplits) {
    IntervalSet s;
    s.add({1, 3});
    s.add({5, 7});
    s.add({3, 5});
    ASSERT_EQ(s.ranges().size(), 1u);
    EXPECT_EQ(s.ranges()[0], (Range{1, 7}));
    s.subtract({2, 4});
    ASSERT_EQ(s.ranges().size(), 2u);
    EXPECT_EQ(s.ranges()[0], (Range{1, 2}));
    EXPECT_EQ(s.ranges()[1], (Range{4, 7}));
    EXPECT_TRUE(s.overlaps({1, 2}));
    EXPECT_FALSE(s.overlaps({2, 4}));
    EXPECT_TRUE(s.overlaps({3, 5}));
    EXPECT_TRUE(s.contains({4, 7}));
    EXPECT_FALSE(s.contains({1, 5}));
    EXPECT_EQ(s.total(), 4u);
    EXPECT_EQ(s.max_end(1), 7u);
}

TEST_F(SchedulerTest, FirstLeaseIsOneIterationThenSizedByRate) {
    scheduler.add_job("a", 0, 1, JobState::Queued, frames(1, 1000));
    auto g = scheduler.lease("w");
    ASSERT_TRUE(g);
    EXPECT_EQ(g->range, (Range{1, 2}));
    EXPECT_EQ(scheduler.state("a"), JobState::Running);
    LeaseGrant out;
    // 1 iteration in 0.1 s: 10 it/s, so a 3 s lease is 30 iterations.
    ASSERT_EQ(scheduler.begin_merge(g->lease_id, 0.1, &out), MergeDecision::Accept);
    scheduler.end_merge(out);
    auto g2 = scheduler.lease("w");
    ASSERT_TRUE(g2);
    EXPECT_EQ(g2->range, (Range{2, 32}));
    // Another worker has no measured rate yet.
    auto g3 = scheduler.lease("other");
    ASSERT_TRUE(g3);
    EXPECT_EQ(g3->range, (Range{32, 33}));
}

TEST_F(SchedulerTest, RangesAreCappedByTheTarget) {
    scheduler.add_job("a", 0, 1, JobState::Queued, frames(1, 5));
    auto g = scheduler.lease("w");
    LeaseGrant out;
    ASSERT_EQ(scheduler.begin_merge(g->lease_id, 0.001, &out), MergeDecision::Accept);
    scheduler.end_merge(out);
    auto g2 = scheduler.lease("w");
    ASSERT_TRUE(g2);
    EXPECT_EQ(g2->range, (Range{2, 6}));
    EXPECT_FALSE(scheduler.lease("w"));
}

TEST_F(SchedulerTest, DuplicateReportIsDropped) {
    scheduler.add_job("a", 0, 1, JobState::Queued, frames(1, 10));
    auto g = scheduler.lease("w");
    LeaseGrant out;
    EXPECT_EQ(scheduler.begin_merge(g->lease_id, 1, &out), MergeDecision::Accept);
    // A second report of the same lease while the first is still being added.
    EXPECT_NE(scheduler.begin_merge(g->lease_id, 1, &out), MergeDecision::Accept);
    scheduler.end_merge(out);
    EXPECT_NE(scheduler.begin_merge(g->lease_id, 1, &out), MergeDecision::Accept);
    EXPECT_EQ(scheduler.begin_merge("nonsense", 1, &out), MergeDecision::UnknownLease);
    EXPECT_EQ(scheduler.progress("a", 0).merged, 1u);
}

TEST_F(SchedulerTest, ExpiredLeaseIsRequeuedAndLateReportDropped) {
    scheduler.add_job("a", 0, 1, JobState::Queued, frames(1, 3));
    auto dead = scheduler.lease("dead");
    ASSERT_TRUE(dead);
    EXPECT_EQ(dead->range, (Range{1, 2}));
    clock.advance(11);  // past the 10 s lease timeout
    auto again = scheduler.lease("alive");
    ASSERT_TRUE(again);
    EXPECT_EQ(again->range, (Range{1, 2}));  // the expired range comes back first
    // The dead worker's heartbeat is told to stop.
    auto cancelled = scheduler.heartbeat("dead", {dead->lease_id});
    ASSERT_EQ(cancelled.size(), 1u);
    LeaseGrant out;
    ASSERT_EQ(scheduler.begin_merge(again->lease_id, 1, &out), MergeDecision::Accept);
    scheduler.end_merge(out);
    // The late report of the reissued range is dropped.
    EXPECT_NE(scheduler.begin_merge(dead->lease_id, 1, &out), MergeDecision::Accept);
    EXPECT_EQ(scheduler.progress("a", 0).merged, 1u);
    EXPECT_EQ(drain("alive"), 2u);
    EXPECT_EQ(scheduler.state("a"), JobState::Done);
    EXPECT_EQ(scheduler.progress("a", 0).merged, 3u);
}

TEST_F(SchedulerTest, ExpiredButNotReissuedReportStillMerges) {
    scheduler.add_job("a", 0, 1, JobState::Queued, frames(1, 3));
    auto slow = scheduler.lease("slow");
    clock.advance(11);
    EXPECT_TRUE(scheduler.heartbeat("slow", {slow->lease_id}).empty());  // still salvageable
    LeaseGrant out;
    ASSERT_EQ(scheduler.begin_merge(slow->lease_id, 1, &out), MergeDecision::Accept);
    scheduler.end_merge(out);
    auto next = scheduler.lease("w");
    ASSERT_TRUE(next);
    EXPECT_EQ(next->range.first, 2u);  // [1, 2) is not handed out again
}

TEST_F(SchedulerTest, HeartbeatKeepsLeasesAlive) {
    scheduler.add_job("a", 0, 1, JobState::Queued, frames(1, 3));
    auto g = scheduler.lease("w");
    for (int i = 0; i < 5; ++i) {
        clock.advance(6);
        EXPECT_TRUE(scheduler.heartbeat("w", {g->lease_id}).empty());
    }
    LeaseGrant out;
    EXPECT_EQ(scheduler.begin_merge(g->lease_id, 1, &out), MergeDecision::Accept);
}

// The worker sends a finished lease's report in the background and leases its next range at
// once (worker/background_report.h): the server grants it a second lease, and the heartbeats
// it sends for the lease it renders keep the one whose report is in flight alive too.
TEST_F(SchedulerTest, AReportInFlightStaysAliveWhileItsWorkerRendersTheNextLease) {
    scheduler.add_job("a", 0, 1, JobState::Queued, frames(1, 3));
    auto in_flight = scheduler.lease("w");
    auto rendering = scheduler.lease("w");
    ASSERT_TRUE(in_flight && rendering);
    EXPECT_EQ(in_flight->range, (Range{1, 2}));
    EXPECT_EQ(rendering->range, (Range{2, 3}));
    EXPECT_EQ(scheduler.worker_leases("w").size(), 2u);
    for (int i = 0; i < 5; ++i) {  // 30 s of heartbeats naming only the lease being rendered
        clock.advance(6);
        EXPECT_TRUE(scheduler.heartbeat("w", {rendering->lease_id}).empty());
    }
    EXPECT_TRUE(scheduler.take_expired().empty());
    auto other = scheduler.lease("x");
    ASSERT_TRUE(other);
    EXPECT_EQ(other->range, (Range{3, 4}));  // neither of w's ranges is handed out again
    LeaseGrant out;
    ASSERT_EQ(scheduler.begin_merge(in_flight->lease_id, 1, &out), MergeDecision::Accept);
    scheduler.end_merge(out);
    ASSERT_EQ(scheduler.begin_merge(rendering->lease_id, 1, &out), MergeDecision::Accept);
    scheduler.end_merge(out);
    EXPECT_EQ(scheduler.progress("a", 0).merged, 2u);
}

// A worker killed with a report in flight and its next lease: both expire, both ranges are
// leased again, and the lost report, should it still arrive, is not merged a second time.
TEST_F(SchedulerTest, AWorkerKilledWithAReportInFlightLosesBothRangesToTheQueue) {
    scheduler.add_job("a", 0, 1, JobState::Queued, frames(1, 2));
    auto in_flight = scheduler.lease("dead");
    auto rendering = scheduler.lease("dead");
    ASSERT_TRUE(in_flight && rendering);
    clock.advance(11);
    EXPECT_EQ(scheduler.tick().size(), 0u);
    EXPECT_EQ(scheduler.take_expired().size(), 2u);
    EXPECT_EQ(drain("alive"), 2u);
    EXPECT_EQ(scheduler.state("a"), JobState::Done);
    LeaseGrant out;
    EXPECT_NE(scheduler.begin_merge(in_flight->lease_id, 1, &out), MergeDecision::Accept);
    EXPECT_EQ(scheduler.progress("a", 0).merged, 2u);
}

TEST_F(SchedulerTest, PriorityThenSubmissionOrder) {
    scheduler.add_job("low", 0, 1, JobState::Queued, frames(1, 1));
    scheduler.add_job("high-late", 5, 3, JobState::Queued, frames(1, 1));
    scheduler.add_job("high-early", 5, 2, JobState::Queued, frames(1, 1));
    EXPECT_EQ(scheduler.lease("w")->job_id, "high-early");
    EXPECT_EQ(scheduler.lease("w")->job_id, "high-late");
    EXPECT_EQ(scheduler.lease("w")->job_id, "low");
    EXPECT_FALSE(scheduler.lease("w"));
}

TEST_F(SchedulerTest, CancelStopsLeasesAndDropsReports) {
    scheduler.add_job("a", 0, 1, JobState::Queued, frames(1, 100));
    scheduler.add_job("b", 0, 2, JobState::Queued, frames(1, 1));
    auto g = scheduler.lease("w");
    ASSERT_EQ(g->job_id, "a");
    scheduler.set_state("a", JobState::Cancelled);
    EXPECT_EQ(scheduler.heartbeat("w", {g->lease_id}).size(), 1u);
    LeaseGrant out;
    EXPECT_NE(scheduler.begin_merge(g->lease_id, 1, &out), MergeDecision::Accept);
    EXPECT_EQ(scheduler.lease("w")->job_id, "b");  // the queue moves on
}

TEST_F(SchedulerTest, FramesCompleteInTurnAndTheJobIsDone) {
    scheduler.add_job("a", 0, 1, JobState::Queued, frames(3, 4));
    EXPECT_EQ(drain("w"), 12u);
    EXPECT_EQ(scheduler.state("a"), JobState::Done);
    for (uint32_t f = 0; f < 3; ++f) EXPECT_TRUE(scheduler.progress("a", f).done);
}

TEST_F(SchedulerTest, RestoredFrameRequeuesTheGapsOnly) {
    std::vector<FramePlan> plan = frames(1, 10);
    plan[0].merged.add({1, 3});
    plan[0].merged.add({5, 6});
    scheduler.add_job("a", 0, 1, JobState::Running, std::move(plan));
    auto g = scheduler.lease("w");
    EXPECT_EQ(g->range, (Range{3, 4}));
    LeaseGrant out;
    ASSERT_EQ(scheduler.begin_merge(g->lease_id, 1e-6, &out), MergeDecision::Accept);
    scheduler.end_merge(out);
    auto g2 = scheduler.lease("w");
    EXPECT_EQ(g2->range, (Range{4, 5}));  // the rest of the gap, not past it
    ASSERT_EQ(scheduler.begin_merge(g2->lease_id, 1e-6, &out), MergeDecision::Accept);
    scheduler.end_merge(out);
    auto g3 = scheduler.lease("w");
    EXPECT_EQ(g3->range, (Range{6, 11}));
}

TEST_F(SchedulerTest, TimeBudgetClosesTheFrame) {
    scheduler.add_job("a", 0, 1, JobState::Queued, frames(1, 0, 5.0));
    auto g = scheduler.lease("w");
    LeaseGrant out;
    ASSERT_EQ(scheduler.begin_merge(g->lease_id, 1.0, &out), MergeDecision::Accept);
    scheduler.end_merge(out);
    EXPECT_TRUE(scheduler.tick().empty());
    clock.advance(6);
    EXPECT_FALSE(scheduler.lease("w"));
    auto complete = scheduler.tick();
    ASSERT_EQ(complete.size(), 1u);
    EXPECT_TRUE(scheduler.finish_frame("a", 0));
    EXPECT_EQ(scheduler.progress("a", 0).merged, 1u);
}

TEST_F(SchedulerTest, LeaseCountersAndQueuedIterations) {
    scheduler.add_job("a", 0, 1, JobState::Queued, frames(1, 10));
    EXPECT_EQ(scheduler.queued_iterations(), 10u);
    auto dead = scheduler.lease("dead");
    ASSERT_TRUE(dead);
    EXPECT_EQ(scheduler.queued_iterations(), 9u);
    auto failed = scheduler.lease("failing");
    ASSERT_TRUE(failed);
    EXPECT_EQ(scheduler.lease_counters().granted, 2u);
    EXPECT_EQ(scheduler.queued_iterations(), 8u);
    // A given-up lease is released (requeued), an unheard one expires (requeued too).
    ASSERT_TRUE(scheduler.release("failing", failed->lease_id));
    EXPECT_FALSE(scheduler.release("failing", failed->lease_id));  // counted once
    EXPECT_EQ(scheduler.queued_iterations(), 9u);
    clock.advance(11);
    scheduler.tick();
    EXPECT_EQ(scheduler.lease_counters().expired, 1u);
    EXPECT_EQ(scheduler.lease_counters().released, 1u);
    EXPECT_EQ(scheduler.queued_iterations(), 10u);
    EXPECT_EQ(scheduler.active_lease_count(), 0u);
    scheduler.set_state("a", JobState::Cancelled);
    EXPECT_EQ(scheduler.queued_iterations(), 0u);
}

TEST_F(SchedulerTest, ClosedFrameCompletesWithTheIterationsHandedOut) {
    // A target error reached: the frame takes no new iterations, the ones out finish.
    scheduler.add_job("a", 0, 1, JobState::Queued, frames(1, 1000));
    auto first = scheduler.lease("w");
    LeaseGrant out;
    ASSERT_EQ(scheduler.begin_merge(first->lease_id, 0.1, &out), MergeDecision::Accept);
    scheduler.end_merge(out);
    auto second = scheduler.lease("w");  // [2, 32)
    ASSERT_TRUE(second);
    scheduler.close_frame("a", 0);
    EXPECT_FALSE(scheduler.lease("other"));
    EXPECT_TRUE(scheduler.tick().empty());  // [2, 32) still out
    ASSERT_EQ(scheduler.begin_merge(second->lease_id, 1, &out), MergeDecision::Accept);
    scheduler.end_merge(out);
    auto complete = scheduler.tick();
    ASSERT_EQ(complete.size(), 1u);
    EXPECT_TRUE(scheduler.finish_frame("a", 0));
    EXPECT_EQ(scheduler.progress("a", 0).merged, 31u);  // iterations 1 to 31
    EXPECT_EQ(scheduler.merged_ranges("a", 0), (std::vector<Range>{{1, 32}}));
}

TEST_F(SchedulerTest, PriorityChangeReordersLeases) {
    scheduler.add_job("a", 0, 1, JobState::Queued, frames(1, 10));
    scheduler.add_job("b", 0, 2, JobState::Queued, frames(1, 10));
    EXPECT_EQ(scheduler.lease("w")->job_id, "a");
    EXPECT_TRUE(scheduler.set_priority("b", 5));
    EXPECT_FALSE(scheduler.set_priority("nonsense", 5));
    EXPECT_EQ(scheduler.lease("w")->job_id, "b");
}

namespace {

// The size of the worker's second lease of a fresh job after its first, one-iteration lease
// took `iteration_seconds` (the measured rate is then exactly 1 / iteration_seconds).
uint64_t lease_after_one_iteration(Scheduler& scheduler, const std::string& job,
                                   double iteration_seconds, double report_cost = -1) {
    scheduler.add_job(job, 0, 1, JobState::Queued, frames(1, 1000000));
    if (report_cost >= 0) scheduler.note_report_cost(job, report_cost);
    auto g = scheduler.lease("w");
    EXPECT_TRUE(g && g->job_id == job && g->range.size() == 1u);
    LeaseGrant out;
    EXPECT_EQ(scheduler.begin_merge(g->lease_id, iteration_seconds, &out), MergeDecision::Accept);
    scheduler.end_merge(out);
    const uint64_t n = scheduler.lease_size("w", job);
    scheduler.set_state(job, JobState::Cancelled);  // out of the way of the next job
    return n;
}

}  // namespace

TEST_F(SchedulerTest, LeasesLastAtLeastTheTargetAndAtMostTheLongestWhateverTheIteration) {
    // target 3 s, longest 30 s (SchedulerOptions defaults, as the server's).
    EXPECT_EQ(scheduler.lease_size("w", "unknown"), 1u);  // rate not measured yet
    struct Case {
        double iteration_seconds;
        uint64_t expected;
    };
    const Case cases[] = {
        {0.001, 3000},  // fast: grown to 3 s
        {0.1, 30},
        {1.0, 3},
        {1.6, 2},   // was 1 (a lease of 1.6 s): now 3.2 s, at least the target
        {2.9, 2},   // 5.8 s: two iterations rather than reports every 2.9 s
        {3.0, 1},   // one iteration already lasts the target
        {10.0, 1},  // slow: one iteration, never less
        {29.0, 1},
        {60.0, 1},   // longer than the longest lease: still one (heartbeats keep it alive)
        {600.0, 1},  // ten minutes per iteration: one
    };
    int k = 0;
    for (const Case& c : cases) {
        const uint64_t n =
            lease_after_one_iteration(scheduler, "job" + std::to_string(k++), c.iteration_seconds);
        EXPECT_EQ(n, c.expected) << "iteration of " << c.iteration_seconds << " s";
        const double seconds = double(n) * c.iteration_seconds;
        // One worker reports at most every 3 s, and at least every 30 s unless one iteration
        // alone takes longer.
        EXPECT_GE(seconds, 3.0 - 1e-9) << c.iteration_seconds;
        if (n > 1) {
            EXPECT_LE(seconds, 30.0 + 1e-9) << c.iteration_seconds;
        }
    }
}

TEST_F(SchedulerTest, ACostlyMergeLengthensTheJobsLeasesUpToTheLongest) {
    // Merging a report costs 0.1 s (a large frame): at most 1 % of render time, so leases
    // of at least 10 s, i.e. 100 iterations at 10 it/s.
    EXPECT_EQ(lease_after_one_iteration(scheduler, "big", 0.1, 0.1), 100u);
    // A 1 s merge would ask for 100 s: capped at the longest lease, 30 s.
    EXPECT_EQ(lease_after_one_iteration(scheduler, "huge", 0.1, 1.0), 300u);
    // A cheap merge leaves the target of 3 s.
    EXPECT_EQ(lease_after_one_iteration(scheduler, "small", 0.1, 0.001), 30u);
    // The cost is a running average over the job's reports.
    scheduler.add_job("avg", 0, 1, JobState::Queued, frames(1, 100));
    scheduler.note_report_cost("avg", 0.2);
    scheduler.note_report_cost("avg", 0.0);  // average 0.1 s: 10 s leases
    auto g = scheduler.lease("w");
    LeaseGrant out;
    ASSERT_EQ(scheduler.begin_merge(g->lease_id, 0.5, &out), MergeDecision::Accept);
    scheduler.end_merge(out);
    EXPECT_EQ(scheduler.lease_size("w", "avg"), 20u);  // 2 it/s for 10 s
    scheduler.note_report_cost("nonsense", 1.0);       // unknown job: ignored
}
