// The PostgreSQL store's connection pool (server/store/pg_connection_pool.h) against a real
// PostgreSQL of the test's own (postgres_instance.h; the cases skip, with the reason, where
// PostgreSQL is not installed): as many operations at once as it has connections and no more,
// a broken connection replaced, and no statement ever run on a connection whose last
// transaction failed.

#include <gtest/gtest.h>

#include <pqxx/pqxx>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "server/store/pg_connection_pool.h"
#include "tests/unit/server/postgres_instance.h"

using namespace render::server;

namespace {

class PgConnectionPoolTest : public ::testing::Test {
  protected:
    void SetUp() override {
        pg_ = std::make_unique<render::testing::PostgresInstance>();
        if (!pg_->start_error().empty()) FAIL() << pg_->start_error();
        if (!pg_->skip_reason().empty()) GTEST_SKIP() << pg_->skip_reason();
    }
    std::unique_ptr<render::testing::PostgresInstance> pg_;
};

// The backend process serving `c`: tells one connection from another.
int backend_pid(pqxx::connection& c) {
    pqxx::nontransaction n(c);
    return n.exec1("SELECT pg_backend_pid()")[0].as<int>();
}

// Waits (without timing anything: a bounded number of short sleeps) until `done()`.
template <class Done>
bool eventually(Done done) {
    for (int i = 0; i < 2000 && !done(); ++i)
        std::this_thread::sleep_for(std::chrono::milliseconds(5));
    return done();
}

}  // namespace

// Four operations hold the pool's four connections at once (each on its own backend); a fifth
// waits until one of them gives its connection back, and then gets that very connection.
TEST_F(PgConnectionPoolTest, LendsEachConnectionToOneOperationAtATime) {
    constexpr size_t kSize = 4;
    PgConnectionPool pool(pg_->url(), kSize, nullptr);
    std::vector<std::optional<PgConnectionPool::Borrowed>> held;
    std::set<int> pids;
    for (size_t i = 0; i < kSize; ++i) {
        held.emplace_back(pool.borrow());
        pids.insert(backend_pid(**held.back()));
    }
    EXPECT_EQ(pids.size(), kSize) << "two operations shared a connection";
    EXPECT_EQ(pool.stats().in_use, kSize);

    std::atomic<bool> got{false};
    std::atomic<int> waiter_pid{0};
    std::thread waiter([&] {
        auto c = pool.borrow();
        got = true;
        waiter_pid = backend_pid(*c);
    });
    ASSERT_TRUE(eventually([&] { return pool.stats().waiting == 1; }));
    EXPECT_FALSE(got.load()) << "a fifth connection was lent from a pool of four";
    const int freed = backend_pid(**held[2]);
    held[2].reset();  // gives its connection back
    waiter.join();
    EXPECT_TRUE(got.load());
    EXPECT_EQ(waiter_pid.load(), freed);
    const PgConnectionPool::Stats stats = pool.stats();
    EXPECT_EQ(stats.connections_made, kSize);
    EXPECT_EQ(stats.waited, 1u);
    EXPECT_EQ(stats.in_use, kSize - 1);
}

// Many threads through a small pool: every operation runs, never two on one connection at
// once (each marks its backend busy and checks nobody else had), and no more connections are
// made than the pool's size.
TEST_F(PgConnectionPoolTest, ManyThreadsShareFewConnectionsWithoutOverlap) {
    constexpr size_t kSize = 3;
    constexpr int kThreads = 8, kOperations = 40;
    PgConnectionPool pool(pg_->url(), kSize, nullptr);
    std::mutex mu;
    std::set<int> busy;
    std::atomic<int> overlaps{0}, done{0};
    std::vector<std::thread> threads;
    for (int t = 0; t < kThreads; ++t)
        threads.emplace_back([&] {
            for (int k = 0; k < kOperations; ++k)
                pool.run([&](pqxx::connection& c) {
                    const int pid = backend_pid(c);
                    {
                        std::lock_guard lock(mu);
                        if (!busy.insert(pid).second) ++overlaps;
                    }
                    pqxx::work w(c);
                    w.exec("SELECT pg_sleep(0.001)");
                    w.commit();
                    {
                        std::lock_guard lock(mu);
                        busy.erase(pid);
                    }
                    ++done;
                });
        });
    for (std::thread& t : threads) t.join();
    EXPECT_EQ(overlaps.load(), 0);
    EXPECT_EQ(done.load(), kThreads * kOperations);
    const PgConnectionPool::Stats stats = pool.stats();
    EXPECT_LE(stats.connections_made, kSize);
    EXPECT_EQ(stats.borrowed, uint64_t(kThreads * kOperations));
    EXPECT_EQ(stats.in_use, 0u);
}

// A connection whose backend was killed (a database restart, a failover, an administrator's
// pg_terminate_backend) fails at most the one operation that finds it broken; the next gets a
// new connection, made with the pool's setup (its prepared statement works).
TEST_F(PgConnectionPoolTest, ABrokenConnectionIsReplaced) {
    PgConnectionPool pool(pg_->url(), 1,
                          [](pqxx::connection& c) { c.prepare("answer", "SELECT 42"); });
    const int first = pool.run([](pqxx::connection& c) { return backend_pid(c); });
    ASSERT_TRUE(pg_->psql("SELECT pg_terminate_backend(" + std::to_string(first) + ")"));
    int failures = 0, second = 0;
    for (int attempt = 0; attempt < 3 && second == 0; ++attempt) {
        try {
            second = pool.run([](pqxx::connection& c) {
                {
                    pqxx::nontransaction n(c);
                    EXPECT_EQ(n.exec_prepared1("answer")[0].as<int>(), 42);
                }
                return backend_pid(c);
            });
        } catch (const std::exception& e) {
            std::printf("attempt %d: %s\n", attempt, e.what());
            ++failures;
        }
    }
    ASSERT_NE(second, 0) << failures << " failed attempts";
    EXPECT_LE(failures, 1);
    EXPECT_NE(second, first);
    EXPECT_EQ(pool.stats().connections_made, 2u);
}

// An operation whose statement failed inside a transaction leaves its connection in a failed
// transaction, where every statement would be refused ("current transaction is aborted").
// The pool never lends it again: the next operation runs on a new backend and succeeds, also
// when the failed operation had caught the error itself and only then thrown.
TEST_F(PgConnectionPoolTest, NoStatementRunsOnAConnectionInAFailedTransaction) {
    PgConnectionPool pool(pg_->url(), 1, nullptr);
    int failed_pid = 0;
    EXPECT_THROW(pool.run([&](pqxx::connection& c) {
        failed_pid = backend_pid(c);
        pqxx::nontransaction n(c);
        n.exec("BEGIN");  // a transaction libpqxx does not know of: nothing rolls it back
        try {
            n.exec("SELECT 1 / 0");
        } catch (const pqxx::sql_error&) {
            throw std::runtime_error("the operation failed");
        }
    }),
                 std::runtime_error);
    int pid = 0;
    EXPECT_NO_THROW(pid = pool.run([](pqxx::connection& c) {
        {
            pqxx::nontransaction n(c);
            n.exec("SELECT 1");
        }
        return backend_pid(c);
    }));
    EXPECT_NE(pid, failed_pid);

    // The same through libpqxx's own transaction, failing on a constraint.
    pool.run([](pqxx::connection& c) {
        pqxx::nontransaction n(c);
        n.exec("CREATE TABLE t (k INTEGER PRIMARY KEY)");
        n.exec("INSERT INTO t VALUES (1)");
    });
    EXPECT_THROW(pool.run([](pqxx::connection& c) {
        pqxx::work w(c);
        w.exec("INSERT INTO t VALUES (1)");
        w.commit();
    }),
                 pqxx::sql_error);
    const int rows = pool.run([](pqxx::connection& c) {
        pqxx::work w(c);
        w.exec("INSERT INTO t VALUES (2)");
        w.commit();
        pqxx::nontransaction n(c);
        return n.exec1("SELECT COUNT(*) FROM t")[0].as<int>();
    });
    EXPECT_EQ(rows, 2);
}

// Connecting fails (nothing listens there): the operation throws, and the slot is free for
// the next attempt rather than lost (a pool of one would otherwise wait for ever).
TEST_F(PgConnectionPoolTest, AFailedConnectLeavesTheSlotFree) {
    PgConnectionPool pool("postgresql://render@127.0.0.1:1/postgres", 1, nullptr);
    EXPECT_THROW(pool.borrow(), std::runtime_error);
    EXPECT_THROW(pool.borrow(), std::runtime_error);
    EXPECT_EQ(pool.stats().in_use, 0u);
    EXPECT_EQ(pool.stats().connections_made, 0u);
}

// The database cut every connection (a restart, a failover): the one operation that finds its
// connection broken fails, and the idle connections are made again with it, so that the next
// operations, all at once, succeed rather than each failing once.
TEST_F(PgConnectionPoolTest, OneBrokenConnectionRenewsTheIdleOnes) {
    constexpr size_t kSize = 3;
    PgConnectionPool pool(pg_->url(), kSize, nullptr);
    pool.fill();
    ASSERT_EQ(pool.stats().connections_made, kSize);
    ASSERT_TRUE(
        pg_->psql("SELECT pg_terminate_backend(pid) FROM pg_stat_activity WHERE "
                  "usename = 'render' AND pid <> pg_backend_pid()"));
    EXPECT_ANY_THROW(pool.run([](pqxx::connection& c) { return backend_pid(c); }));
    std::vector<PgConnectionPool::Borrowed> held;
    for (size_t i = 0; i < kSize; ++i) held.push_back(pool.borrow());
    int failures = 0;
    for (auto& c : held) {
        try {
            backend_pid(*c);
        } catch (const std::exception&) {
            ++failures;
        }
    }
    EXPECT_EQ(failures, 0);
    EXPECT_EQ(pool.stats().connections_made, 2 * kSize);
}
