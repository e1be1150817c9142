#include "server/store/postgres_job_store.h"

#include <pqxx/pqxx>

#include <stdexcept>

namespace render::server {

namespace {

// Serialises schema migrations between servers starting at once on one database: an
// advisory lock's key, arbitrary but fixed ("RNDR").
constexpr int64_t kMigrationLockKey = 0x524e4452;

// The statements of each migration (docs/design/job-store.md, "Migrations"); the same
// versions as the SQLite store's, in PostgreSQL's types.
const char* const kMigrations[] = {
    // 1: the queue's tables.
    R"(CREATE TABLE IF NOT EXISTS jobs (
        id TEXT PRIMARY KEY, seq BIGINT NOT NULL, name TEXT, state INTEGER NOT NULL,
        priority INTEGER NOT NULL, request BYTEA NOT NULL, width INTEGER, height INTEGER,
        error TEXT, submitted_ms BIGINT);
    CREATE TABLE IF NOT EXISTS frames (
        job_id TEXT NOT NULL, idx BIGINT NOT NULL, done INTEGER NOT NULL DEFAULT 0,
        elapsed DOUBLE PRECISION NOT NULL DEFAULT 0, PRIMARY KEY (job_id, idx));
    CREATE TABLE IF NOT EXISTS assets (
        sha256 TEXT PRIMARY KEY, size BIGINT NOT NULL, added_ms BIGINT);
    CREATE TABLE IF NOT EXISTS merged_ranges (
        job_id TEXT NOT NULL, frame BIGINT NOT NULL, first BIGINT NOT NULL,
        end_ BIGINT NOT NULL, PRIMARY KEY (job_id, frame, first));
    CREATE TABLE IF NOT EXISTS leases (
        lease_id TEXT PRIMARY KEY, worker_id TEXT, job_id TEXT, frame BIGINT,
        first BIGINT, end_ BIGINT,
        issued_ms BIGINT DEFAULT (EXTRACT(EPOCH FROM now()) * 1000)::BIGINT))",
    // 2: the retention rule's finish time.
    "ALTER TABLE jobs ADD COLUMN IF NOT EXISTS finished_ms BIGINT",
    // 3: claim_lease looks up a frame's leases.
    "CREATE INDEX IF NOT EXISTS leases_by_frame ON leases (job_id, frame)",
    // 4: which server holds a job's sums, until when, in which epoch.
    "ALTER TABLE jobs ADD COLUMN IF NOT EXISTS owner TEXT, "
    "ADD COLUMN IF NOT EXISTS owner_address TEXT, "
    "ADD COLUMN IF NOT EXISTS owner_epoch BIGINT NOT NULL DEFAULT 0, "
    "ADD COLUMN IF NOT EXISTS owner_until_ms BIGINT",
};
static_assert(std::size(kMigrations) == size_t(kJobStoreSchemaVersion));

// The database's clock in Unix milliseconds: every server's holds are judged by one clock.
#define RENDER_PG_NOW_MS "(EXTRACT(EPOCH FROM clock_timestamp()) * 1000)::BIGINT"

int64_t i64(uint64_t v) {
    return int64_t(v);
}

// The frame's merged ranges replaced by `ranges`, inside `w`.
void replace_ranges(pqxx::work& w, const std::string& job_id, uint32_t frame,
                    const std::vector<Range>& ranges) {
    w.exec_params("DELETE FROM merged_ranges WHERE job_id = $1 AND frame = $2", job_id,
                  int64_t(frame));
    for (const Range& r : ranges)
        w.exec_params(
            "INSERT INTO merged_ranges (job_id, frame, first, end_) VALUES ($1, $2, $3, $4) "
            "ON CONFLICT (job_id, frame, first) DO UPDATE SET end_ = EXCLUDED.end_",
            job_id, int64_t(frame), i64(r.first), i64(r.end));
}

void delete_asset_rows(pqxx::work& w, const std::vector<std::string>& assets) {
    for (const std::string& sha : assets)
        w.exec_params("DELETE FROM assets WHERE sha256 = $1", sha);
}

}  // namespace

struct PostgresJobStore::Connection {
    explicit Connection(const std::string& url) : c(url) {}
    pqxx::connection c;
};

PostgresJobStore::PostgresJobStore(const std::string& url) : url_(url) {
    connect();
    migrate();
}

void PostgresJobStore::connect() {
    connection_.reset();
    try {
        connection_ = std::make_unique<Connection>(url_);
    } catch (const std::exception& e) {
        // libpq's message may quote the URI, password included: not repeated here.
        throw std::runtime_error(std::string("cannot connect to PostgreSQL: ") + e.what());
    }
    {
        pqxx::nontransaction n(connection_->c);
        // CREATE ... IF NOT EXISTS would print a NOTICE for every table that exists.
        n.exec("SET client_min_messages = warning");
    }
    connection_->c.prepare("insert_lease",
                           "INSERT INTO leases (lease_id, worker_id, job_id, frame, first, end_) "
                           "VALUES ($1, $2, $3, $4, $5, $6) ON CONFLICT (lease_id) DO UPDATE SET "
                           "worker_id = EXCLUDED.worker_id, job_id = EXCLUDED.job_id, "
                           "frame = EXCLUDED.frame, first = EXCLUDED.first, end_ = EXCLUDED.end_, "
                           "issued_ms = EXCLUDED.issued_ms");
    connection_->c.prepare("delete_lease", "DELETE FROM leases WHERE lease_id = $1");
}

PostgresJobStore::Connection& PostgresJobStore::live() {
    // The operation that found the connection broken (the database restarted, a failover)
    // failed; the next one connects again rather than relying on libpqxx's deprecated
    // implicit reactivation.
    if (!connection_ || !connection_->c.is_open()) connect();
    return *connection_;
}

PostgresJobStore::~PostgresJobStore() = default;

void PostgresJobStore::migrate() {
    pqxx::work w(live().c);
    w.exec_params("SELECT pg_advisory_xact_lock($1)", kMigrationLockKey);
    w.exec("CREATE TABLE IF NOT EXISTS schema_version (version INTEGER NOT NULL)");
    const int version =
        w.exec1("SELECT COALESCE(MAX(version), 0) FROM schema_version")[0].as<int>();
    if (version > kJobStoreSchemaVersion)
        throw std::runtime_error("the store's schema is version " + std::to_string(version) +
                                 ", newer than this server's " +
                                 std::to_string(kJobStoreSchemaVersion));
    if (version == kJobStoreSchemaVersion) return;
    // PostgreSQL's DDL is transactional: every migration and the new version commit together.
    for (int next = version + 1; next <= kJobStoreSchemaVersion; ++next)
        w.exec(kMigrations[next - 1]);
    w.exec("DELETE FROM schema_version");
    w.exec_params("INSERT INTO schema_version (version) VALUES ($1)", kJobStoreSchemaVersion);
    w.commit();
}

int PostgresJobStore::schema_version() {
    std::lock_guard lock(mu_);
    pqxx::work w(live().c);
    return w.exec1("SELECT COALESCE(MAX(version), 0) FROM schema_version")[0].as<int>();
}

void PostgresJobStore::insert_job(const JobRow& job, uint32_t frame_count) {
    std::lock_guard lock(mu_);
    pqxx::work w(live().c);
    w.exec_params(
        "INSERT INTO jobs (id, seq, name, state, priority, request, width, height, error, "
        "submitted_ms) VALUES ($1, $2, $3, $4, $5, $6, $7, $8, $9, $10)",
        job.id, job.sequence, job.name, job.state, job.priority, pqxx::binarystring(job.request),
        job.width, job.height, job.error, job.submitted_unix_ms);
    w.exec_params("INSERT INTO frames (job_id, idx) SELECT $1, generate_series(0, $2::BIGINT - 1)",
                  job.id, int64_t(frame_count));
    w.commit();
}

void PostgresJobStore::update_job_priority(const std::string& job_id, int priority) {
    std::lock_guard lock(mu_);
    pqxx::work w(live().c);
    w.exec_params("UPDATE jobs SET priority = $2 WHERE id = $1", job_id, priority);
    w.commit();
}

void PostgresJobStore::update_job_state(const std::string& job_id, int state,
                                        const std::string& error, int64_t finished_ms) {
    std::lock_guard lock(mu_);
    pqxx::work w(live().c);
    w.exec_params(
        "UPDATE jobs SET state = $2, error = $3, "
        "finished_ms = CASE WHEN $4::BIGINT > 0 THEN $4::BIGINT ELSE finished_ms END "
        "WHERE id = $1",
        job_id, state, error, finished_ms);
    w.commit();
}

void PostgresJobStore::update_frame(const std::string& job_id, uint32_t frame, bool done,
                                    double elapsed) {
    std::lock_guard lock(mu_);
    pqxx::work w(live().c);
    w.exec_params("UPDATE frames SET done = $3, elapsed = $4 WHERE job_id = $1 AND idx = $2",
                  job_id, int64_t(frame), done ? 1 : 0, elapsed);
    w.commit();
}

std::vector<JobRow> PostgresJobStore::load_jobs() {
    std::lock_guard lock(mu_);
    pqxx::work w(live().c);
    pqxx::result rows = w.exec(
        "SELECT id, seq, COALESCE(name, ''), state, priority, request, COALESCE(width, 0), "
        "COALESCE(height, 0), COALESCE(error, ''), COALESCE(submitted_ms, 0), "
        "COALESCE(finished_ms, 0), COALESCE(owner, ''), COALESCE(owner_address, ''), "
        "owner_epoch, (owner IS NOT NULL AND owner_until_ms >= " RENDER_PG_NOW_MS
        ") FROM jobs ORDER BY seq");
    std::vector<JobRow> out;
    for (const pqxx::row& row : rows) {
        JobRow r;
        r.id = row[0].as<std::string>();
        r.sequence = row[1].as<int64_t>();
        r.name = row[2].as<std::string>();
        r.state = row[3].as<int>();
        r.priority = row[4].as<int>();
        r.request = pqxx::binarystring(row[5]).str();
        r.width = row[6].as<int>();
        r.height = row[7].as<int>();
        r.error = row[8].as<std::string>();
        r.submitted_unix_ms = row[9].as<int64_t>();
        r.finished_unix_ms = row[10].as<int64_t>();
        r.owner.server = row[11].as<std::string>();
        r.owner.address = row[12].as<std::string>();
        r.owner.epoch = row[13].as<int64_t>();
        r.owner.live = row[14].as<bool>();
        out.push_back(std::move(r));
    }
    return out;
}

std::vector<FrameRow> PostgresJobStore::load_frames(const std::string& job_id) {
    std::lock_guard lock(mu_);
    pqxx::work w(live().c);
    pqxx::result rows = w.exec_params(
        "SELECT idx, done, elapsed FROM frames WHERE job_id = $1 ORDER BY idx", job_id);
    std::vector<FrameRow> out;
    for (const pqxx::row& row : rows)
        out.push_back({uint32_t(row[0].as<int64_t>()), row[1].as<int>() != 0, row[2].as<double>()});
    return out;
}

int64_t PostgresJobStore::max_sequence() {
    std::lock_guard lock(mu_);
    pqxx::work w(live().c);
    return w.exec1("SELECT COALESCE(MAX(seq), 0) FROM jobs")[0].as<int64_t>();
}

void PostgresJobStore::add_merged_range(const std::string& job_id, uint32_t frame, Range range) {
    std::lock_guard lock(mu_);
    pqxx::work w(live().c);
    w.exec_params(
        "INSERT INTO merged_ranges (job_id, frame, first, end_) VALUES ($1, $2, $3, $4) "
        "ON CONFLICT (job_id, frame, first) DO UPDATE SET end_ = EXCLUDED.end_",
        job_id, int64_t(frame), i64(range.first), i64(range.end));
    w.commit();
}

void PostgresJobStore::set_merged_ranges(const std::string& job_id, uint32_t frame,
                                         const std::vector<Range>& ranges) {
    std::lock_guard lock(mu_);
    pqxx::work w(live().c);
    replace_ranges(w, job_id, frame, ranges);
    w.commit();
}

std::vector<Range> PostgresJobStore::merged_ranges(const std::string& job_id, uint32_t frame) {
    std::lock_guard lock(mu_);
    pqxx::work w(live().c);
    pqxx::result rows = w.exec_params(
        "SELECT first, end_ FROM merged_ranges WHERE job_id = $1 AND frame = $2 ORDER BY first",
        job_id, int64_t(frame));
    std::vector<Range> out;
    for (const pqxx::row& row : rows)
        out.push_back({uint64_t(row[0].as<int64_t>()), uint64_t(row[1].as<int64_t>())});
    return out;
}

void PostgresJobStore::save_frame(const std::string& job_id, uint32_t frame,
                                  const std::vector<Range>& ranges, bool done, double elapsed,
                                  int64_t hold_epoch) {
    std::lock_guard lock(mu_);
    pqxx::work w(live().c);
    // The fence: FOR SHARE holds a take_job (an UPDATE of the row) back until this commits.
    if (hold_epoch != 0 &&
        w.exec_params("SELECT 1 FROM jobs WHERE id = $1 AND owner IS NOT NULL AND "
                      "owner_epoch = $2 FOR SHARE",
                      job_id, hold_epoch)
            .empty())
        throw HoldLost("the hold of job " + job_id + " in epoch " + std::to_string(hold_epoch) +
                       " is lost");
    replace_ranges(w, job_id, frame, ranges);
    w.exec_params("UPDATE frames SET done = $3, elapsed = $4 WHERE job_id = $1 AND idx = $2",
                  job_id, int64_t(frame), done ? 1 : 0, elapsed);
    w.commit();
}

void PostgresJobStore::add_asset(const std::string& sha256, uint64_t size) {
    std::lock_guard lock(mu_);
    pqxx::work w(live().c);
    w.exec_params(
        "INSERT INTO assets (sha256, size, added_ms) "
        "VALUES ($1, $2, (EXTRACT(EPOCH FROM now()) * 1000)::BIGINT) "
        "ON CONFLICT (sha256) DO NOTHING",
        sha256, i64(size));
    w.commit();
}

void PostgresJobStore::delete_assets(const std::vector<std::string>& assets) {
    std::lock_guard lock(mu_);
    pqxx::work w(live().c);
    delete_asset_rows(w, assets);
    w.commit();
}

void PostgresJobStore::delete_job(const std::string& job_id,
                                  const std::vector<std::string>& assets) {
    std::lock_guard lock(mu_);
    pqxx::work w(live().c);
    for (const char* sql :
         {"DELETE FROM jobs WHERE id = $1", "DELETE FROM frames WHERE job_id = $1",
          "DELETE FROM merged_ranges WHERE job_id = $1", "DELETE FROM leases WHERE job_id = $1"})
        w.exec_params(sql, job_id);
    delete_asset_rows(w, assets);
    w.commit();
}

void PostgresJobStore::insert_lease(const std::string& lease_id, const std::string& worker_id,
                                    const std::string& job_id, uint32_t frame, Range range) {
    std::lock_guard lock(mu_);
    pqxx::work w(live().c);
    w.exec_prepared("insert_lease", lease_id, worker_id, job_id, int64_t(frame), i64(range.first),
                    i64(range.end));
    w.commit();
}

bool PostgresJobStore::claim_lease(const LeaseRow& lease) {
    std::lock_guard lock(mu_);
    pqxx::work w(live().c);
    // The frame's row lock: a claim on the same frame from any connection waits here until
    // this transaction ends, then (READ COMMITTED: each statement sees what committed before
    // it) finds this lease in its overlap check.
    pqxx::result frame =
        w.exec_params("SELECT 1 FROM frames WHERE job_id = $1 AND idx = $2 FOR UPDATE",
                      lease.job_id, int64_t(lease.frame));
    if (frame.empty()) return false;  // no such frame; the transaction rolls back
    pqxx::result overlap = w.exec_params(
        "SELECT 1 FROM leases WHERE job_id = $1 AND frame = $2 AND first < $4 AND end_ > $3 "
        "UNION ALL SELECT 1 FROM merged_ranges WHERE job_id = $1 AND frame = $2 AND first < $4 "
        "AND end_ > $3 LIMIT 1",
        lease.job_id, int64_t(lease.frame), i64(lease.range.first), i64(lease.range.end));
    if (!overlap.empty()) return false;
    w.exec_params(
        "INSERT INTO leases (lease_id, worker_id, job_id, frame, first, end_) "
        "VALUES ($1, $2, $3, $4, $5, $6)",
        lease.lease_id, lease.worker_id, lease.job_id, int64_t(lease.frame), i64(lease.range.first),
        i64(lease.range.end));
    w.commit();
    return true;
}

void PostgresJobStore::delete_lease(const std::string& lease_id) {
    std::lock_guard lock(mu_);
    pqxx::work w(live().c);
    w.exec_prepared("delete_lease", lease_id);
    w.commit();
}

std::vector<LeaseRow> PostgresJobStore::load_leases() {
    std::lock_guard lock(mu_);
    pqxx::work w(live().c);
    pqxx::result rows = w.exec(
        "SELECT lease_id, COALESCE(worker_id, ''), job_id, frame, first, end_ FROM leases "
        "ORDER BY job_id, frame, first");
    std::vector<LeaseRow> out;
    for (const pqxx::row& row : rows)
        out.push_back({row[0].as<std::string>(), row[1].as<std::string>(), row[2].as<std::string>(),
                       uint32_t(row[3].as<int64_t>()),
                       Range{uint64_t(row[4].as<int64_t>()), uint64_t(row[5].as<int64_t>())}});
    return out;
}

std::optional<LeaseRow> PostgresJobStore::find_lease(const std::string& lease_id) {
    std::lock_guard lock(mu_);
    pqxx::work w(live().c);
    pqxx::result rows = w.exec_params(
        "SELECT lease_id, COALESCE(worker_id, ''), job_id, frame, first, end_ FROM leases "
        "WHERE lease_id = $1",
        lease_id);
    if (rows.empty()) return std::nullopt;
    const pqxx::row row = rows[0];
    return LeaseRow{row[0].as<std::string>(), row[1].as<std::string>(), row[2].as<std::string>(),
                    uint32_t(row[3].as<int64_t>()),
                    Range{uint64_t(row[4].as<int64_t>()), uint64_t(row[5].as<int64_t>())}};
}

int PostgresJobStore::clear_leases() {
    std::lock_guard lock(mu_);
    pqxx::work w(live().c);
    pqxx::result r = w.exec("DELETE FROM leases");
    w.commit();
    return int(r.affected_rows());
}

int PostgresJobStore::clear_job_leases(const std::string& job_id) {
    std::lock_guard lock(mu_);
    pqxx::work w(live().c);
    pqxx::result r = w.exec_params("DELETE FROM leases WHERE job_id = $1", job_id);
    w.commit();
    return int(r.affected_rows());
}

std::optional<int64_t> PostgresJobStore::take_job(const std::string& job_id,
                                                  const std::string& server,
                                                  const std::string& address, int64_t hold_ms) {
    std::lock_guard lock(mu_);
    pqxx::work w(live().c);
    // One UPDATE: of two servers taking the job at once, the second waits for the first's row
    // lock and then finds the condition false (READ COMMITTED re-checks the updated row).
    pqxx::result r = w.exec_params(
        "UPDATE jobs SET owner = $2, owner_address = $3, owner_epoch = owner_epoch + 1, "
        "owner_until_ms = " RENDER_PG_NOW_MS
        " + $4 WHERE id = $1 AND (owner IS NULL OR "
        "owner_until_ms < " RENDER_PG_NOW_MS ") RETURNING owner_epoch",
        job_id, server, address, hold_ms);
    w.commit();
    if (r.empty()) return std::nullopt;
    return r[0][0].as<int64_t>();
}

bool PostgresJobStore::renew_job(const std::string& job_id, const std::string& server,
                                 int64_t epoch, int64_t hold_ms) {
    std::lock_guard lock(mu_);
    pqxx::work w(live().c);
    pqxx::result r = w.exec_params("UPDATE jobs SET owner_until_ms = " RENDER_PG_NOW_MS
                                   " + $4 WHERE id = $1 AND owner = $2 AND owner_epoch = $3",
                                   job_id, server, epoch, hold_ms);
    w.commit();
    return r.affected_rows() == 1;
}

void PostgresJobStore::release_job(const std::string& job_id, const std::string& server,
                                   int64_t epoch) {
    std::lock_guard lock(mu_);
    pqxx::work w(live().c);
    w.exec_params(
        "UPDATE jobs SET owner = NULL, owner_until_ms = NULL WHERE id = $1 AND owner = $2 AND "
        "owner_epoch = $3",
        job_id, server, epoch);
    w.commit();
}

}  // namespace render::server
