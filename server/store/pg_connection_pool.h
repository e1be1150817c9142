#pragma once

// A fixed number of PostgreSQL connections shared by a server's threads
// (docs/design/job-store.md, "Connections"). An operation borrows one connection for its whole
// transaction and gives it back; when every connection is out, it waits for one. A connection
// that broke, or whose operation threw, is closed and made again before it is lent next: a
// statement never runs on a connection whose last transaction failed. One connection found
// broken closes the idle ones too (a database restart cut them all): a restart costs the
// operations in flight, not one more per connection.

#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <exception>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include <pqxx/connection>

namespace render::server {

class PgConnectionPool {
  public:
    // Called on every new connection (prepared statements, session settings).
    using Setup = std::function<void(pqxx::connection&)>;

    // Figures for metrics and tests.
    struct Stats {
        size_t size = 0;
        size_t in_use = 0;
        size_t waiting = 0;             // operations waiting for a connection now
        uint64_t connections_made = 0;  // first connections and replacements
        uint64_t borrowed = 0;          // operations run
        uint64_t waited = 0;            // operations that found every connection out
        double wait_seconds = 0;        // their waiting, summed
    };

    // `size` connections at most (at least 1), made on first use; `url` a libpq URI.
    PgConnectionPool(std::string url, size_t size, Setup setup);
    ~PgConnectionPool();
    PgConnectionPool(const PgConnectionPool&) = delete;
    PgConnectionPool& operator=(const PgConnectionPool&) = delete;

    // One connection, lent until destroyed. A Borrowed destroyed while an exception unwinds
    // (its operation threw) closes its connection: the next borrower gets a new one.
    class Borrowed {
      public:
        Borrowed(Borrowed&& other) noexcept;
        Borrowed& operator=(Borrowed&&) = delete;
        ~Borrowed();
        pqxx::connection& operator*() const { return *connection_; }
        pqxx::connection* operator->() const { return connection_; }
        // Closes the connection when given back, whether or not an exception unwinds.
        void discard() { discard_ = true; }

      private:
        friend class PgConnectionPool;
        Borrowed(PgConnectionPool& pool, size_t slot, pqxx::connection* connection);
        PgConnectionPool* pool_;
        size_t slot_;
        pqxx::connection* connection_;
        int exceptions_;  // std::uncaught_exceptions() when lent
        bool discard_ = false;
    };

    // A free connection (connected, or connected again, first), waiting while all are out;
    // std::runtime_error when connecting fails (the slot stays free for the next try).
    Borrowed borrow();

    // Makes every connection now (a server at start: a database that refuses that many
    // connections is found at once, not under load).
    void fill();

    // `operation(connection)` on a borrowed connection; its result or its exception.
    template <class Operation>
    auto run(Operation&& operation) {
        Borrowed c = borrow();
        return operation(*c);
    }

    Stats stats() const;
    size_t size() const { return slots_.size(); }

  private:
    // `discard`: the connection is closed; `broken`: it was found cut, and so are the idle ones.
    void give_back(size_t slot, bool discard, bool broken);
    const std::string url_;
    const Setup setup_;
    mutable std::mutex mu_;
    std::condition_variable freed_;
    struct Slot {
        std::unique_ptr<pqxx::connection> connection;
        bool lent = false;
    };
    std::vector<Slot> slots_;
    Stats stats_;
};

}  // namespace render::server
