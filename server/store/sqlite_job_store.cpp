#include "server/store/sqlite_job_store.h"

#include <sqlite3.h>

#include <stdexcept>

namespace render::server {

namespace {

// The database's clock (the machine's) in Unix milliseconds.
#define RENDER_SQLITE_NOW_MS "CAST((julianday('now') - 2440587.5) * 86400000 AS INTEGER)"

sqlite3_stmt* prepare(sqlite3* db, const char* sql) {
    sqlite3_stmt* stmt = nullptr;
    if (sqlite3_prepare_v2(db, sql, -1, &stmt, nullptr) != SQLITE_OK)
        throw std::runtime_error(std::string("sqlite prepare: ") + sqlite3_errmsg(db));
    return stmt;
}

// A prepared statement that finalizes itself, or one prepared once and kept by the store
// (`reused`: reset and unbound when done, for the statements run at every Lease and Report).
class Statement {
  public:
    Statement(sqlite3* db, const char* sql) : db_(db), stmt_(prepare(db, sql)) {}
    Statement(sqlite3* db, sqlite3_stmt* reused) : db_(db), stmt_(reused), owned_(false) {}
    ~Statement() {
        if (owned_) {
            sqlite3_finalize(stmt_);
        } else {
            sqlite3_reset(stmt_);
            sqlite3_clear_bindings(stmt_);
        }
    }
    Statement(const Statement&) = delete;
    Statement& operator=(const Statement&) = delete;

    Statement& bind(int i, const std::string& v) {
        check(sqlite3_bind_blob(stmt_, i, v.data(), int(v.size()), SQLITE_TRANSIENT));
        return *this;
    }
    Statement& text(int i, const std::string& v) {
        check(sqlite3_bind_text(stmt_, i, v.data(), int(v.size()), SQLITE_TRANSIENT));
        return *this;
    }
    Statement& bind(int i, int64_t v) {
        check(sqlite3_bind_int64(stmt_, i, v));
        return *this;
    }
    Statement& bind(int i, double v) {
        check(sqlite3_bind_double(stmt_, i, v));
        return *this;
    }
    // True while there is a row.
    bool step() {
        int rc = sqlite3_step(stmt_);
        if (rc == SQLITE_ROW) return true;
        if (rc == SQLITE_DONE) return false;
        throw std::runtime_error(std::string("sqlite step: ") + sqlite3_errmsg(db_));
    }
    void run() {
        while (step()) {
        }
    }
    int64_t i64(int col) { return sqlite3_column_int64(stmt_, col); }
    double f64(int col) { return sqlite3_column_double(stmt_, col); }
    std::string str(int col) {
        const void* p = sqlite3_column_blob(stmt_, col);
        int n = sqlite3_column_bytes(stmt_, col);
        return p ? std::string(static_cast<const char*>(p), size_t(n)) : std::string();
    }

  private:
    void check(int rc) {
        if (rc != SQLITE_OK)
            throw std::runtime_error(std::string("sqlite bind: ") + sqlite3_errmsg(db_));
    }
    sqlite3* db_;
    sqlite3_stmt* stmt_ = nullptr;
    bool owned_ = true;
};

// Whether `table` has a column `column` (stores from older versions lack newer columns).
bool has_column(sqlite3* db, const char* table, const char* column) {
    Statement s(db, (std::string("PRAGMA table_info(") + table + ")").c_str());
    while (s.step())
        if (s.str(1) == column) return true;
    return false;
}

}  // namespace

SqliteJobStore::SqliteJobStore(const std::filesystem::path& database) {
    if (sqlite3_open_v2(database.c_str(), &db_,
                        SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE | SQLITE_OPEN_FULLMUTEX,
                        nullptr) != SQLITE_OK) {
        std::string message = db_ ? sqlite3_errmsg(db_) : "out of memory";
        sqlite3_close(db_);
        throw std::runtime_error("cannot open database " + database.string() + ": " + message);
    }
    sqlite3_busy_timeout(db_, 5000);
    exec("PRAGMA journal_mode=WAL");
    exec("PRAGMA synchronous=NORMAL");
    migrate();
    insert_lease_ =
        prepare(db_,
                "INSERT OR REPLACE INTO leases (lease_id, worker_id, job_id, frame, first, end_) "
                "VALUES (?1, ?2, ?3, ?4, ?5, ?6)");
    delete_lease_ = prepare(db_, "DELETE FROM leases WHERE lease_id = ?1");
}

void SqliteJobStore::migrate() {
    exec("CREATE TABLE IF NOT EXISTS schema_version (version INTEGER NOT NULL)");
    int version = read_schema_version();
    if (version > kJobStoreSchemaVersion)
        throw std::runtime_error("the store's schema is version " + std::to_string(version) +
                                 ", newer than this server's " +
                                 std::to_string(kJobStoreSchemaVersion));
    // Stores made before the schema was versioned hold no row: version 0, and migrations 1
    // and 2 find their tables and column already there.
    for (int next = version + 1; next <= kJobStoreSchemaVersion; ++next) {
        exec("BEGIN IMMEDIATE");
        try {
            apply_migration(next);
            exec("DELETE FROM schema_version");
            Statement s(db_, "INSERT INTO schema_version (version) VALUES (?1)");
            s.bind(1, int64_t(next));
            s.run();
            exec("COMMIT");
        } catch (...) {
            exec("ROLLBACK");
            throw;
        }
    }
}

void SqliteJobStore::apply_migration(int version) {
    switch (version) {
        case 1:
            exec(R"(CREATE TABLE IF NOT EXISTS jobs (
            id TEXT PRIMARY KEY, seq INTEGER NOT NULL, name TEXT, state INTEGER NOT NULL,
            priority INTEGER NOT NULL, request BLOB NOT NULL, width INTEGER, height INTEGER,
            error TEXT, submitted_ms INTEGER))");
            exec(R"(CREATE TABLE IF NOT EXISTS frames (
            job_id TEXT NOT NULL, idx INTEGER NOT NULL, done INTEGER NOT NULL DEFAULT 0,
            elapsed REAL NOT NULL DEFAULT 0, PRIMARY KEY (job_id, idx)))");
            exec(R"(CREATE TABLE IF NOT EXISTS assets (
            sha256 TEXT PRIMARY KEY, size INTEGER NOT NULL, added_ms INTEGER))");
            exec(R"(CREATE TABLE IF NOT EXISTS merged_ranges (
            job_id TEXT NOT NULL, frame INTEGER NOT NULL, first INTEGER NOT NULL,
            end_ INTEGER NOT NULL, PRIMARY KEY (job_id, frame, first)))");
            exec(R"(CREATE TABLE IF NOT EXISTS leases (
            lease_id TEXT PRIMARY KEY, worker_id TEXT, job_id TEXT, frame INTEGER,
            first INTEGER, end_ INTEGER,
            issued_ms INTEGER DEFAULT (strftime('%s','now') * 1000)))");
            break;
        case 2:
            // The retention rule's finish time (NULL reads as 0); stores made between the rule
            // and the versioned schema have it already.
            if (!has_column(db_, "jobs", "finished_ms"))
                exec("ALTER TABLE jobs ADD COLUMN finished_ms INTEGER");
            break;
        case 3:
            // claim_lease looks up a frame's leases.
            exec("CREATE INDEX IF NOT EXISTS leases_by_frame ON leases (job_id, frame)");
            break;
        case 4:
            // Which server holds a job's sums (one server per SQLite file: always this one).
            if (!has_column(db_, "jobs", "owner")) {
                exec("ALTER TABLE jobs ADD COLUMN owner TEXT");
                exec("ALTER TABLE jobs ADD COLUMN owner_address TEXT");
                exec("ALTER TABLE jobs ADD COLUMN owner_epoch INTEGER NOT NULL DEFAULT 0");
                exec("ALTER TABLE jobs ADD COLUMN owner_until_ms INTEGER");
            }
            break;
        case 5:
            // The farm's workers as each server saw them (PostgreSQL also gets its claim
            // function; one server per SQLite file claims in BEGIN IMMEDIATE).
            exec(R"(CREATE TABLE IF NOT EXISTS farm_workers (
            worker_id TEXT NOT NULL, server TEXT NOT NULL, server_address TEXT, host TEXT,
            threads INTEGER, version TEXT, seen_ms INTEGER, iterations_per_second REAL,
            samples_per_second REAL, rays_per_second REAL, recorded_ms INTEGER,
            PRIMARY KEY (server, worker_id)))");
            break;
        default:
            throw std::logic_error("no migration to version " + std::to_string(version));
    }
}

int SqliteJobStore::schema_version() {
    std::lock_guard lock(mu_);
    return read_schema_version();
}

int SqliteJobStore::read_schema_version() {
    Statement s(db_, "SELECT COALESCE(MAX(version), 0) FROM schema_version");
    return s.step() ? int(s.i64(0)) : 0;
}

SqliteJobStore::~SqliteJobStore() {
    sqlite3_finalize(insert_lease_);
    sqlite3_finalize(delete_lease_);
    sqlite3_close(db_);
}

void SqliteJobStore::exec(const char* sql) {
    char* error = nullptr;
    if (sqlite3_exec(db_, sql, nullptr, nullptr, &error) != SQLITE_OK) {
        std::string message = error ? error : "unknown error";
        sqlite3_free(error);
        throw std::runtime_error("sqlite: " + message);
    }
}

void SqliteJobStore::insert_job(const JobRow& job, uint32_t frame_count) {
    std::lock_guard lock(mu_);
    exec("BEGIN IMMEDIATE");
    try {
        Statement s(db_,
                    "INSERT INTO jobs (id, seq, name, state, priority, request, width, height, "
                    "error, submitted_ms) VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10)");
        s.text(1, job.id)
            .bind(2, int64_t(job.sequence))
            .text(3, job.name)
            .bind(4, int64_t(job.state))
            .bind(5, int64_t(job.priority))
            .bind(6, job.request)
            .bind(7, int64_t(job.width))
            .bind(8, int64_t(job.height))
            .text(9, job.error)
            .bind(10, job.submitted_unix_ms);
        s.run();
        for (uint32_t i = 0; i < frame_count; ++i) {
            Statement fi(db_, "INSERT INTO frames (job_id, idx) VALUES (?1, ?2)");
            fi.text(1, job.id).bind(2, int64_t(i));
            fi.run();
        }
        exec("COMMIT");
    } catch (...) {
        exec("ROLLBACK");
        throw;
    }
}

void SqliteJobStore::update_job_priority(const std::string& job_id, int priority) {
    std::lock_guard lock(mu_);
    Statement s(db_, "UPDATE jobs SET priority = ?2 WHERE id = ?1");
    s.text(1, job_id).bind(2, int64_t(priority));
    s.run();
}

void SqliteJobStore::update_job_state(const std::string& job_id, int state,
                                      const std::string& error, int64_t finished_ms) {
    std::lock_guard lock(mu_);
    Statement s(db_,
                "UPDATE jobs SET state = ?2, error = ?3, "
                "finished_ms = CASE WHEN ?4 > 0 THEN ?4 ELSE finished_ms END WHERE id = ?1");
    s.text(1, job_id).bind(2, int64_t(state)).text(3, error).bind(4, finished_ms);
    s.run();
}

void SqliteJobStore::update_frame(const std::string& job_id, uint32_t frame, bool done,
                                  double elapsed) {
    std::lock_guard lock(mu_);
    Statement s(db_, "UPDATE frames SET done = ?3, elapsed = ?4 WHERE job_id = ?1 AND idx = ?2");
    s.text(1, job_id).bind(2, int64_t(frame)).bind(3, int64_t(done ? 1 : 0)).bind(4, elapsed);
    s.run();
}

std::vector<JobRow> SqliteJobStore::load_jobs() {
    std::lock_guard lock(mu_);
    Statement s(db_,
                "SELECT id, seq, name, state, priority, request, width, height, error, "
                "submitted_ms, COALESCE(finished_ms, 0), COALESCE(owner, ''), "
                "COALESCE(owner_address, ''), owner_epoch, (owner IS NOT NULL AND "
                "owner_until_ms >= " RENDER_SQLITE_NOW_MS ") FROM jobs ORDER BY seq");
    std::vector<JobRow> out;
    while (s.step()) {
        JobRow r;
        r.id = s.str(0);
        r.sequence = s.i64(1);
        r.name = s.str(2);
        r.state = int(s.i64(3));
        r.priority = int(s.i64(4));
        r.request = s.str(5);
        r.width = int(s.i64(6));
        r.height = int(s.i64(7));
        r.error = s.str(8);
        r.submitted_unix_ms = s.i64(9);
        r.finished_unix_ms = s.i64(10);
        r.owner.server = s.str(11);
        r.owner.address = s.str(12);
        r.owner.epoch = s.i64(13);
        r.owner.live = s.i64(14) != 0;
        out.push_back(std::move(r));
    }
    return out;
}

std::vector<FrameRow> SqliteJobStore::load_frames(const std::string& job_id) {
    std::lock_guard lock(mu_);
    Statement s(db_, "SELECT idx, done, elapsed FROM frames WHERE job_id = ?1 ORDER BY idx");
    s.text(1, job_id);
    std::vector<FrameRow> out;
    while (s.step()) out.push_back({uint32_t(s.i64(0)), s.i64(1) != 0, s.f64(2)});
    return out;
}

int64_t SqliteJobStore::max_sequence() {
    std::lock_guard lock(mu_);
    Statement s(db_, "SELECT COALESCE(MAX(seq), 0) FROM jobs");
    return s.step() ? s.i64(0) : 0;
}

void SqliteJobStore::add_merged_range(const std::string& job_id, uint32_t frame, Range range) {
    std::lock_guard lock(mu_);
    insert_merged_range(job_id, frame, range);
}

void SqliteJobStore::insert_merged_range(const std::string& job_id, uint32_t frame, Range range) {
    Statement s(db_,
                "INSERT OR REPLACE INTO merged_ranges (job_id, frame, first, end_) "
                "VALUES (?1, ?2, ?3, ?4)");
    s.text(1, job_id)
        .bind(2, int64_t(frame))
        .bind(3, int64_t(range.first))
        .bind(4, int64_t(range.end));
    s.run();
}

void SqliteJobStore::set_merged_ranges(const std::string& job_id, uint32_t frame,
                                       const std::vector<Range>& ranges) {
    std::lock_guard lock(mu_);
    exec("BEGIN IMMEDIATE");
    try {
        replace_merged_ranges(job_id, frame, ranges);
        exec("COMMIT");
    } catch (...) {
        exec("ROLLBACK");
        throw;
    }
}

void SqliteJobStore::replace_merged_ranges(const std::string& job_id, uint32_t frame,
                                           const std::vector<Range>& ranges) {
    Statement d(db_, "DELETE FROM merged_ranges WHERE job_id = ?1 AND frame = ?2");
    d.text(1, job_id).bind(2, int64_t(frame));
    d.run();
    for (const Range& r : ranges) insert_merged_range(job_id, frame, r);
}

void SqliteJobStore::save_frame(const std::string& job_id, uint32_t frame,
                                const std::vector<Range>& ranges, bool done, double elapsed,
                                int64_t hold_epoch) {
    std::lock_guard lock(mu_);
    exec("BEGIN IMMEDIATE");
    try {
        if (hold_epoch != 0) {
            // The fence, as on PostgreSQL (BEGIN IMMEDIATE: no take_job passes meanwhile).
            Statement f(db_,
                        "SELECT 1 FROM jobs WHERE id = ?1 AND owner IS NOT NULL AND "
                        "owner_epoch = ?2");
            f.text(1, job_id).bind(2, hold_epoch);
            if (!f.step())
                throw HoldLost("the hold of job " + job_id + " in epoch " +
                               std::to_string(hold_epoch) + " is lost");
        }
        replace_merged_ranges(job_id, frame, ranges);
        Statement u(db_,
                    "UPDATE frames SET done = ?3, elapsed = ?4 WHERE job_id = ?1 AND idx = ?2");
        u.text(1, job_id).bind(2, int64_t(frame)).bind(3, int64_t(done ? 1 : 0)).bind(4, elapsed);
        u.run();
        exec("COMMIT");
    } catch (...) {
        exec("ROLLBACK");
        throw;
    }
}

std::vector<Range> SqliteJobStore::merged_ranges(const std::string& job_id, uint32_t frame) {
    std::lock_guard lock(mu_);
    Statement s(db_,
                "SELECT first, end_ FROM merged_ranges WHERE job_id = ?1 AND frame = ?2 "
                "ORDER BY first");
    s.text(1, job_id).bind(2, int64_t(frame));
    std::vector<Range> out;
    while (s.step()) out.push_back({uint64_t(s.i64(0)), uint64_t(s.i64(1))});
    return out;
}

void SqliteJobStore::add_asset(const std::string& sha256, uint64_t size) {
    std::lock_guard lock(mu_);
    Statement s(db_,
                "INSERT OR IGNORE INTO assets (sha256, size, added_ms) "
                "VALUES (?1, ?2, strftime('%s','now') * 1000)");
    s.text(1, sha256).bind(2, int64_t(size));
    s.run();
}

void SqliteJobStore::delete_job(const std::string& job_id, const std::vector<std::string>& assets) {
    std::lock_guard lock(mu_);
    exec("BEGIN IMMEDIATE");
    try {
        for (const char* sql :
             {"DELETE FROM jobs WHERE id = ?1", "DELETE FROM frames WHERE job_id = ?1",
              "DELETE FROM merged_ranges WHERE job_id = ?1",
              "DELETE FROM leases WHERE job_id = ?1"}) {
            Statement s(db_, sql);
            s.text(1, job_id);
            s.run();
        }
        delete_asset_rows(assets);
        exec("COMMIT");
    } catch (...) {
        exec("ROLLBACK");
        throw;
    }
}

void SqliteJobStore::delete_asset_rows(const std::vector<std::string>& assets) {
    for (const std::string& sha : assets) {
        Statement s(db_, "DELETE FROM assets WHERE sha256 = ?1");
        s.text(1, sha);
        s.run();
    }
}

void SqliteJobStore::delete_assets(const std::vector<std::string>& assets) {
    std::lock_guard lock(mu_);
    exec("BEGIN IMMEDIATE");
    try {
        delete_asset_rows(assets);
        exec("COMMIT");
    } catch (...) {
        exec("ROLLBACK");
        throw;
    }
}

void SqliteJobStore::insert_lease(const std::string& lease_id, const std::string& worker_id,
                                  const std::string& job_id, uint32_t frame, Range range) {
    std::lock_guard lock(mu_);
    Statement s(db_, insert_lease_);
    s.text(1, lease_id)
        .text(2, worker_id)
        .text(3, job_id)
        .bind(4, int64_t(frame))
        .bind(5, int64_t(range.first))
        .bind(6, int64_t(range.end));
    s.run();
}

void SqliteJobStore::delete_lease(const std::string& lease_id) {
    std::lock_guard lock(mu_);
    Statement s(db_, delete_lease_);
    s.text(1, lease_id);
    s.run();
}

void SqliteJobStore::delete_leases(const std::vector<std::string>& lease_ids) {
    if (lease_ids.empty()) return;
    std::lock_guard lock(mu_);
    exec("BEGIN IMMEDIATE");
    try {
        for (const std::string& id : lease_ids) {
            Statement s(db_, delete_lease_);
            s.text(1, id);
            s.run();
        }
        exec("COMMIT");
    } catch (...) {
        exec("ROLLBACK");
        throw;
    }
}

bool SqliteJobStore::claim_lease(const LeaseRow& lease) {
    std::lock_guard lock(mu_);
    // BEGIN IMMEDIATE takes the database's write lock: no other connection writes between the
    // check and the insert (SQLite locks the whole database, not rows).
    exec("BEGIN IMMEDIATE");
    try {
        Statement frame(db_, "SELECT 1 FROM frames WHERE job_id = ?1 AND idx = ?2");
        frame.text(1, lease.job_id).bind(2, int64_t(lease.frame));
        if (!frame.step()) {
            exec("COMMIT");
            return false;  // no such frame
        }
        Statement overlap(db_,
                          "SELECT 1 FROM leases WHERE job_id = ?1 AND frame = ?2 AND first < ?4 "
                          "AND end_ > ?3 UNION ALL SELECT 1 FROM merged_ranges WHERE job_id = "
                          "?1 AND frame = ?2 AND first < ?4 AND end_ > ?3 LIMIT 1");
        overlap.text(1, lease.job_id)
            .bind(2, int64_t(lease.frame))
            .bind(3, int64_t(lease.range.first))
            .bind(4, int64_t(lease.range.end));
        const bool taken = overlap.step();
        if (!taken) {
            Statement s(db_,
                        "INSERT INTO leases (lease_id, worker_id, job_id, frame, first, end_) "
                        "VALUES (?1, ?2, ?3, ?4, ?5, ?6)");
            s.text(1, lease.lease_id)
                .text(2, lease.worker_id)
                .text(3, lease.job_id)
                .bind(4, int64_t(lease.frame))
                .bind(5, int64_t(lease.range.first))
                .bind(6, int64_t(lease.range.end));
            s.run();
        }
        exec("COMMIT");
        return !taken;
    } catch (...) {
        exec("ROLLBACK");
        throw;
    }
}

std::vector<LeaseRow> SqliteJobStore::load_leases() {
    std::lock_guard lock(mu_);
    Statement s(db_,
                "SELECT lease_id, worker_id, job_id, frame, first, end_ FROM leases "
                "ORDER BY job_id, frame, first");
    std::vector<LeaseRow> out;
    while (s.step())
        out.push_back({s.str(0), s.str(1), s.str(2), uint32_t(s.i64(3)),
                       Range{uint64_t(s.i64(4)), uint64_t(s.i64(5))}});
    return out;
}

std::optional<LeaseRow> SqliteJobStore::find_lease(const std::string& lease_id) {
    std::lock_guard lock(mu_);
    Statement s(db_,
                "SELECT lease_id, worker_id, job_id, frame, first, end_ FROM leases "
                "WHERE lease_id = ?1");
    s.text(1, lease_id);
    if (!s.step()) return std::nullopt;
    return LeaseRow{s.str(0), s.str(1), s.str(2), uint32_t(s.i64(3)),
                    Range{uint64_t(s.i64(4)), uint64_t(s.i64(5))}};
}

int SqliteJobStore::clear_leases() {
    std::lock_guard lock(mu_);
    exec("DELETE FROM leases");
    return sqlite3_changes(db_);
}

int SqliteJobStore::clear_job_leases(const std::string& job_id) {
    std::lock_guard lock(mu_);
    Statement s(db_, "DELETE FROM leases WHERE job_id = ?1");
    s.text(1, job_id);
    s.run();
    return sqlite3_changes(db_);
}

std::optional<int64_t> SqliteJobStore::take_job(const std::string& job_id,
                                                const std::string& server,
                                                const std::string& address, int64_t hold_ms) {
    std::lock_guard lock(mu_);
    Statement s(db_,
                "UPDATE jobs SET owner = ?2, owner_address = ?3, owner_epoch = owner_epoch + 1, "
                "owner_until_ms = " RENDER_SQLITE_NOW_MS
                " + ?4 WHERE id = ?1 AND (owner IS NULL "
                "OR owner_until_ms < " RENDER_SQLITE_NOW_MS ") RETURNING owner_epoch");
    s.text(1, job_id).text(2, server).text(3, address).bind(4, hold_ms);
    if (!s.step()) return std::nullopt;
    const int64_t epoch = s.i64(0);
    s.run();
    return epoch;
}

bool SqliteJobStore::renew_job(const std::string& job_id, const std::string& server, int64_t epoch,
                               int64_t hold_ms) {
    std::lock_guard lock(mu_);
    Statement s(db_, "UPDATE jobs SET owner_until_ms = " RENDER_SQLITE_NOW_MS
                     " + ?4 WHERE id = ?1 AND owner = ?2 AND owner_epoch = ?3");
    s.text(1, job_id).text(2, server).bind(3, epoch).bind(4, hold_ms);
    s.run();
    return sqlite3_changes(db_) == 1;
}

void SqliteJobStore::release_job(const std::string& job_id, const std::string& server,
                                 int64_t epoch) {
    std::lock_guard lock(mu_);
    Statement s(db_,
                "UPDATE jobs SET owner = NULL, owner_until_ms = NULL WHERE id = ?1 AND owner = ?2 "
                "AND owner_epoch = ?3");
    s.text(1, job_id).text(2, server).bind(3, epoch);
    s.run();
}

void SqliteJobStore::record_workers(const std::string& server,
                                    const std::vector<FarmWorkerRow>& workers, int64_t forget_ms) {
    std::lock_guard lock(mu_);
    exec("BEGIN IMMEDIATE");
    try {
        Statement d(
            db_, "DELETE FROM farm_workers WHERE server = ?1 OR recorded_ms < " RENDER_SQLITE_NOW_MS
                 " - ?2");
        d.text(1, server).bind(2, forget_ms);
        d.run();
        for (const FarmWorkerRow& w : workers) {
            Statement s(db_,
                        "INSERT INTO farm_workers (worker_id, server, server_address, host, "
                        "threads, version, seen_ms, iterations_per_second, samples_per_second, "
                        "rays_per_second, recorded_ms) VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, "
                        "?9, ?10, " RENDER_SQLITE_NOW_MS ")");
            s.text(1, w.worker_id)
                .text(2, server)
                .text(3, w.server_address)
                .text(4, w.host)
                .bind(5, int64_t(w.threads))
                .text(6, w.version)
                .bind(7, w.seen_unix_ms)
                .bind(8, w.iterations_per_second)
                .bind(9, w.samples_per_second)
                .bind(10, w.rays_per_second);
            s.run();
        }
        exec("COMMIT");
    } catch (...) {
        exec("ROLLBACK");
        throw;
    }
}

std::vector<FarmWorkerRow> SqliteJobStore::load_workers(int64_t max_age_ms) {
    std::lock_guard lock(mu_);
    Statement s(
        db_,
        "SELECT worker_id, server, COALESCE(server_address, ''), COALESCE(host, ''), "
        "COALESCE(threads, 0), COALESCE(version, ''), COALESCE(seen_ms, 0), "
        "COALESCE(iterations_per_second, 0), COALESCE(samples_per_second, 0), "
        "COALESCE(rays_per_second, 0) FROM farm_workers WHERE recorded_ms >= " RENDER_SQLITE_NOW_MS
        " - ?1 ORDER BY server, worker_id");
    s.bind(1, max_age_ms);
    std::vector<FarmWorkerRow> out;
    while (s.step()) {
        FarmWorkerRow r;
        r.worker_id = s.str(0);
        r.server = s.str(1);
        r.server_address = s.str(2);
        r.host = s.str(3);
        r.threads = uint32_t(s.i64(4));
        r.version = s.str(5);
        r.seen_unix_ms = s.i64(6);
        r.iterations_per_second = s.f64(7);
        r.samples_per_second = s.f64(8);
        r.rays_per_second = s.f64(9);
        out.push_back(std::move(r));
    }
    return out;
}

}  // namespace render::server
