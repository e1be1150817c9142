// The failure policy on its own (server/failure_policy.h): which workers' failures and losses
// make a poison job, what a merged report forgives, and the memory wait.

#include <gtest/gtest.h>

#include <chrono>
#include <iterator>

#include "core/base/memory_budget.h"
#include "server/failure_policy.h"

using namespace render;
using namespace render::server;

namespace {

constexpr size_t kManyWorkers = 50;  // more known workers than any limit

TimePoint at(double seconds) {
    return TimePoint{} + std::chrono::duration_cast<SteadyClock::duration>(
                             std::chrono::duration<double>(seconds));
}

}  // namespace

TEST(FailurePolicy, TwoWorkersReportingAFailureMakeAPoisonJob) {
    JobFailures f;
    f.lease_failed("w1", "l1", "first", false);
    EXPECT_FALSE(f.poison_verdict(kManyWorkers));
    // The same worker again is still one worker.
    f.lease_failed("w1", "l2", "again", false);
    EXPECT_FALSE(f.poison_verdict(kManyWorkers));
    f.lease_failed("w2", "l3", "boom", false);
    EXPECT_EQ(f.poison_verdict(kManyWorkers), "failed on 2 workers; last error: boom");
}

TEST(FailurePolicy, OneReportedFailureIsEnoughWhenTheServerKnowsOneWorker) {
    JobFailures f;
    f.lease_failed("w1", "l1", "bad scene", false);
    EXPECT_EQ(f.poison_verdict(1), "failed on 1 worker; last error: bad scene");
    EXPECT_EQ(f.poison_verdict(0), "failed on 1 worker; last error: bad scene");
    EXPECT_FALSE(f.poison_verdict(2));
}

TEST(FailurePolicy, LostLeasesNeedThreeWorkers) {
    JobFailures f;
    f.lease_lost("w1", "l1");
    f.lease_lost("w2", "l2");
    // Losses do not count as reported failures, even with only two workers known.
    EXPECT_FALSE(f.poison_verdict(2));
    f.lease_lost("w3", "l3");
    EXPECT_EQ(f.poison_verdict(kManyWorkers),
              "failed on 3 workers (3 lost the lease: died or stopped heartbeating while "
              "rendering it); no worker reported an error");
}

TEST(FailurePolicy, FailedAndLostWorkersCountTogether) {
    JobFailures f;
    f.lease_failed("w1", "l1", "crash", false);
    f.lease_lost("w2", "l2");
    EXPECT_FALSE(f.poison_verdict(kManyWorkers));
    f.lease_lost("w3", "l3");
    EXPECT_EQ(f.poison_verdict(kManyWorkers),
              "failed on 3 workers (2 lost the lease: died or stopped heartbeating while "
              "rendering it); last error: crash");
}

TEST(FailurePolicy, LeasesLostAfterProgressCountOnlyTowardTheLargerLimit) {
    JobFailures f;
    const char* names[] = {"a", "b", "c", "d", "e", "f", "g", "h", "i"};
    static_assert(std::size(names) + 1 == kMaxLostRenderingWorkers);
    for (const char* name : names) {
        f.lease_progressed(name);  // worker `name` on its lease `name`
        f.lease_lost(name, name);
    }
    EXPECT_FALSE(f.poison_verdict(kManyWorkers));
    f.lease_progressed("last");
    f.lease_lost("w-last", "last");
    EXPECT_EQ(f.poison_verdict(kManyWorkers),
              "failed on 10 workers (10 lost the lease: died or stopped heartbeating while "
              "rendering it); no worker reported an error");
}

TEST(FailurePolicy, ProgressCountsOnlyForItsOwnLease) {
    JobFailures f;
    f.lease_progressed("l1");
    f.lease_lost("w1", "other");  // not the lease that progressed: a plain loss
    f.lease_lost("w2", "l2");
    f.lease_lost("w3", "l3");
    EXPECT_TRUE(f.poison_verdict(kManyWorkers));
    // A failed lease forgets its progress: losing it later is a plain loss.
    JobFailures g;
    g.lease_progressed("l1");
    g.lease_failed("w1", "l1", "e", false);
    g.lease_lost("w2", "l1");
    g.lease_lost("w3", "l3");
    EXPECT_TRUE(g.poison_verdict(kManyWorkers));
}

TEST(FailurePolicy, AnUndeliveredReportCountsAsALossWhileRendering) {
    JobFailures undelivered;
    undelivered.lease_failed("w1", "l1", "unavailable", true);
    undelivered.lease_failed("w2", "l2", "unavailable", true);
    undelivered.lease_failed("w3", "l3", "unavailable", true);
    EXPECT_FALSE(undelivered.poison_verdict(1));
    JobFailures reported;
    reported.lease_failed("w1", "l1", "unavailable", false);
    EXPECT_TRUE(reported.poison_verdict(1));
}

TEST(FailurePolicy, AnIdleReportStreamCountsAsALossWhileRendering) {
    JobFailures f;
    for (const char* w : {"w1", "w2", "w3", "w4"}) f.report_stream_idle(w, w);
    EXPECT_FALSE(f.poison_verdict(kManyWorkers));
}

TEST(FailurePolicy, AMergedReportForgivesEarlierFailures) {
    JobFailures f;
    f.lease_failed("w1", "l1", "flaky", false);
    f.lease_lost("w2", "l2");
    f.report_merged("l9");
    f.lease_failed("w3", "l3", "flaky", false);
    f.lease_lost("w4", "l4");
    EXPECT_FALSE(f.poison_verdict(kManyWorkers));
    f.lease_failed("w5", "l5", "flaky again", false);
    EXPECT_EQ(f.poison_verdict(kManyWorkers),
              "failed on 3 workers (1 lost the lease: died or stopped heartbeating while "
              "rendering it); last error: flaky again");
}

TEST(FailurePolicy, AWorkerLacksMemoryWhenItRefusedOrItsLimitIsTooSmall) {
    JobFailures f;
    EXPECT_FALSE(f.refused_for_memory());
    EXPECT_FALSE(f.lacks_memory("w1", 1));
    f.refused_for_memory("w1", 1000, 2000, "too big");
    EXPECT_TRUE(f.refused_for_memory());
    EXPECT_EQ(f.memory_needed(), 2000u);
    EXPECT_TRUE(f.lacks_memory("w1", 0));
    EXPECT_TRUE(f.lacks_memory("w1", 1 << 30));  // it refused: not offered again
    EXPECT_FALSE(f.lacks_memory("w2", 0));       // limit unknown: may try
    EXPECT_TRUE(f.lacks_memory("w2", 1999));
    EXPECT_FALSE(f.lacks_memory("w2", 2000));
    // The largest estimate is kept.
    f.refused_for_memory("w3", 500, 1500, "smaller estimate");
    EXPECT_EQ(f.memory_needed(), 2000u);
}

TEST(FailurePolicy, AJobIsMemoryBlockedWhenNoLiveWorkerCanTakeIt) {
    JobFailures f;
    EXPECT_FALSE(f.memory_blocked({{"w1", 0}}));  // never refused
    f.refused_for_memory("w1", 1000, 2000, "too big");
    EXPECT_FALSE(f.memory_blocked({}));  // no live worker: not blocked
    EXPECT_TRUE(f.memory_blocked({{"w1", 1000}}));
    EXPECT_FALSE(f.memory_blocked({{"w1", 1000}, {"w2", 0}}));
    EXPECT_TRUE(f.memory_blocked({{"w1", 1000}, {"w2", 1500}}));
    EXPECT_FALSE(f.memory_blocked({{"w1", 1000}, {"w2", 4000}}));
}

TEST(FailurePolicy, TheMemoryWaitFailsAJobBlockedWithoutABreak) {
    JobFailures f;
    f.refused_for_memory("w1", 1000, 2000, "needs 2000 bytes");
    EXPECT_FALSE(f.memory_wait_verdict(true, at(0), 300));
    EXPECT_FALSE(f.memory_wait_verdict(true, at(299), 300));
    // A worker that could take it joined: the wait starts again.
    EXPECT_FALSE(f.memory_wait_verdict(false, at(299.5), 300));
    EXPECT_FALSE(f.memory_wait_verdict(true, at(310), 300));
    EXPECT_FALSE(f.memory_wait_verdict(true, at(609), 300));
    EXPECT_EQ(f.memory_wait_verdict(true, at(610), 300),
              "no worker has the memory for this job: refused for memory by 1 worker and no "
              "live worker with more joined within 300 s (server --memory-wait); last refusal: "
              "needs 2000 bytes");
}

TEST(FailurePolicy, TheWaitingMessageNamesTheLargestLimitAndTheNeed) {
    JobFailures f;
    f.refused_for_memory("w1", uint64_t(1) << 30, uint64_t(3) << 30, "a");
    f.refused_for_memory("w2", uint64_t(2) << 30, uint64_t(5) << 29, "b");
    EXPECT_EQ(f.memory_waiting(0.5),
              "waiting for a worker with more than " + format_bytes(uint64_t(2) << 30) +
                  " of memory: the job needs at least " + format_bytes(uint64_t(3) << 30) +
                  " (refused for memory by 2 workers; it fails if none joins within 0.5 s, "
                  "server --memory-wait)");
}
