#include "server/store/pg_connection_pool.h"

#include <pqxx/pqxx>

#include <algorithm>
#include <stdexcept>

namespace render::server {

PgConnectionPool::PgConnectionPool(std::string url, size_t size, Setup setup)
    : url_(std::move(url)), setup_(std::move(setup)), slots_(std::max<size_t>(1, size)) {
    stats_.size = slots_.size();
}

PgConnectionPool::~PgConnectionPool() = default;

PgConnectionPool::Borrowed::Borrowed(PgConnectionPool& pool, size_t slot,
                                     pqxx::connection* connection)
    : pool_(&pool), slot_(slot), connection_(connection), exceptions_(std::uncaught_exceptions()) {}

PgConnectionPool::Borrowed::Borrowed(Borrowed&& other) noexcept
    : pool_(other.pool_),
      slot_(other.slot_),
      connection_(other.connection_),
      exceptions_(other.exceptions_),
      discard_(other.discard_) {
    other.pool_ = nullptr;
}

PgConnectionPool::Borrowed::~Borrowed() {
    if (!pool_) return;
    // Unwinding past the operation: its transaction was rolled back by libpqxx, or the
    // connection broke in the middle. Either way the connection is not trusted again.
    const bool failed = discard_ || std::uncaught_exceptions() > exceptions_;
    pool_->give_back(slot_, failed, failed && !connection_->is_open());
}

PgConnectionPool::Borrowed PgConnectionPool::borrow() {
    size_t slot = 0;
    bool connect = false;
    {
        std::unique_lock lock(mu_);
        auto free_slot = [&] {
            for (size_t i = 0; i < slots_.size(); ++i)
                if (!slots_[i].lent) return i;
            return slots_.size();
        };
        slot = free_slot();
        if (slot == slots_.size()) {
            // Every connection out: wait, and count the wait (where the servers wait,
            // docs/results/service-measurements.md).
            const auto start = std::chrono::steady_clock::now();
            ++stats_.waiting;
            freed_.wait(lock, [&] { return (slot = free_slot()) != slots_.size(); });
            --stats_.waiting;
            ++stats_.waited;
            stats_.wait_seconds +=
                std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
        }
        Slot& s = slots_[slot];
        s.lent = true;
        ++stats_.in_use;
        ++stats_.borrowed;
        connect = !s.connection || !s.connection->is_open();
        if (connect) s.connection.reset();
    }
    if (connect) {
        // Outside mu_: the other connections stay usable while this one is made.
        std::unique_ptr<pqxx::connection> made;
        try {
            made = std::make_unique<pqxx::connection>(url_);
            if (setup_) setup_(*made);
        } catch (const std::exception& e) {
            give_back(slot, true, false);
            // libpq's message may quote the URI, password included: not repeated here.
            throw std::runtime_error(std::string("cannot connect to PostgreSQL: ") + e.what());
        }
        std::lock_guard lock(mu_);
        slots_[slot].connection = std::move(made);
        ++stats_.connections_made;
    }
    std::lock_guard lock(mu_);
    return Borrowed(*this, slot, slots_[slot].connection.get());
}

void PgConnectionPool::fill() {
    std::vector<Borrowed> all;
    for (size_t i = 0; i < slots_.size(); ++i) all.push_back(borrow());
}

void PgConnectionPool::give_back(size_t slot, bool discard, bool broken) {
    std::vector<std::unique_ptr<pqxx::connection>> closing;
    {
        std::lock_guard lock(mu_);
        Slot& s = slots_[slot];
        if (discard) closing.push_back(std::move(s.connection));
        // A connection found broken: the database restarted or failed over, and the idle
        // connections were most likely cut with it. They are made again when next lent
        // rather than each failing one operation first.
        if (broken)
            for (Slot& other : slots_)
                if (!other.lent && other.connection) closing.push_back(std::move(other.connection));
        s.lent = false;
        --stats_.in_use;
    }
    freed_.notify_one();
    // `closing` is destroyed here, outside mu_ (closing a connection may block).
}

PgConnectionPool::Stats PgConnectionPool::stats() const {
    std::lock_guard lock(mu_);
    return stats_;
}

}  // namespace render::server
