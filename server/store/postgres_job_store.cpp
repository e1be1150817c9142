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
    // 5: claim_lease in one round trip, and the farm's workers as each server last saw them.
    // In a VOLATILE PL/pgSQL function under READ COMMITTED each statement takes a new
    // snapshot: the overlap check, after waiting for the frame's row lock, sees every lease
    // committed meanwhile, as the separate statements of a client-side transaction did.
    R"(CREATE OR REPLACE FUNCTION render_claim_lease(p_lease TEXT, p_worker TEXT, p_job TEXT,
        p_frame BIGINT, p_first BIGINT, p_end BIGINT) RETURNS BOOLEAN VOLATILE
    LANGUAGE plpgsql AS $$
    BEGIN
        PERFORM 1 FROM frames WHERE job_id = p_job AND idx = p_frame FOR UPDATE;
        IF NOT FOUND THEN RETURN FALSE; END IF;
        IF EXISTS (SELECT 1 FROM leases WHERE job_id = p_job AND frame = p_frame
                   AND first < p_end AND end_ > p_first)
           OR EXISTS (SELECT 1 FROM merged_ranges WHERE job_id = p_job AND frame = p_frame
                      AND first < p_end AND end_ > p_first) THEN
            RETURN FALSE;
        END IF;
        INSERT INTO leases (lease_id, worker_id, job_id, frame, first, end_)
            VALUES (p_lease, p_worker, p_job, p_frame, p_first, p_end);
        RETURN TRUE;
    END $$;
    CREATE TABLE IF NOT EXISTS farm_workers (
        worker_id TEXT NOT NULL, server TEXT NOT NULL, server_address TEXT, host TEXT,
        threads BIGINT, version TEXT, seen_ms BIGINT, iterations_per_second DOUBLE PRECISION,
        samples_per_second DOUBLE PRECISION, rays_per_second DOUBLE PRECISION,
        recorded_ms BIGINT, PRIMARY KEY (server, worker_id)))",
};
static_assert(std::size(kMigrations) == size_t(kJobStoreSchemaVersion));

// The database's clock in Unix milliseconds: every server's holds are judged by one clock.
#define RENDER_PG_NOW_MS "(EXTRACT(EPOCH FROM clock_timestamp()) * 1000)::BIGINT"

int64_t i64(uint64_t v) {
    return int64_t(v);
}

// The frame's merged ranges replaced by `ranges`, inside `w`.
// A PostgreSQL array literal of integers ("{1,2,3}"), for one statement over many rows.
template <class Get>
std::string int_array(const std::vector<Range>& ranges, Get get) {
    std::string out = "{";
    for (size_t i = 0; i < ranges.size(); ++i) {
        if (i) out += ',';
        out += std::to_string(get(ranges[i]));
    }
    return out + "}";
}

// The frame's merged ranges replaced by `ranges`, inside `w`: two statements however many
// ranges (docs/design/job-store.md, "Connections").
void replace_ranges(pqxx::transaction_base& w, const std::string& job_id, uint32_t frame,
                    const std::vector<Range>& ranges) {
    w.exec_params("DELETE FROM merged_ranges WHERE job_id = $1 AND frame = $2", job_id,
                  int64_t(frame));
    if (ranges.empty()) return;
    w.exec_params(
        "INSERT INTO merged_ranges (job_id, frame, first, end_) "
        "SELECT $1, $2, f, e FROM unnest($3::BIGINT[], $4::BIGINT[]) AS r(f, e) "
        "ON CONFLICT (job_id, frame, first) DO UPDATE SET end_ = EXCLUDED.end_",
        job_id, int64_t(frame), int_array(ranges, [](const Range& r) { return i64(r.first); }),
        int_array(ranges, [](const Range& r) { return i64(r.end); }));
}

// A PostgreSQL array literal of texts, every element double-quoted, " and \ escaped.
std::string text_array(const std::vector<std::string>& values) {
    std::string out = "{";
    for (size_t i = 0; i < values.size(); ++i) {
        if (i) out += ',';
        out += '"';
        for (char ch : values[i]) {
            if (ch == '"' || ch == '\\') out += '\\';
            out += ch;
        }
        out += '"';
    }
    return out + "}";
}

template <class T, class Get>
std::string number_array(const std::vector<T>& rows, Get get) {
    std::string out = "{";
    for (size_t i = 0; i < rows.size(); ++i) {
        if (i) out += ',';
        out += pqxx::to_string(get(rows[i]));
    }
    return out + "}";
}

template <class Get>
std::string text_column(const std::vector<FarmWorkerRow>& rows, Get get) {
    std::vector<std::string> values;
    for (const FarmWorkerRow& r : rows) values.push_back(get(r));
    return text_array(values);
}

void delete_asset_rows(pqxx::transaction_base& w, const std::vector<std::string>& assets) {
    for (const std::string& sha : assets)
        w.exec_params("DELETE FROM assets WHERE sha256 = $1", sha);
}

}  // namespace

PostgresJobStore::PostgresJobStore(const std::string& url, size_t connections)
    : pool_(url, connections, [](pqxx::connection& c) {
          pqxx::nontransaction n(c);
          // CREATE ... IF NOT EXISTS would print a NOTICE for every table that exists.
          n.exec("SET client_min_messages = warning");
          c.prepare("insert_lease",
                    "INSERT INTO leases (lease_id, worker_id, job_id, frame, first, end_) "
                    "VALUES ($1, $2, $3, $4, $5, $6) ON CONFLICT (lease_id) DO UPDATE SET "
                    "worker_id = EXCLUDED.worker_id, job_id = EXCLUDED.job_id, "
                    "frame = EXCLUDED.frame, first = EXCLUDED.first, end_ = EXCLUDED.end_, "
                    "issued_ms = EXCLUDED.issued_ms");
          c.prepare("delete_lease", "DELETE FROM leases WHERE lease_id = $1");
      }) {
    migrate();
    pool_.fill();
}

PostgresJobStore::~PostgresJobStore() = default;

void PostgresJobStore::migrate() {
    auto c = pool_.borrow();
    pqxx::work w(*c);
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
    auto c = pool_.borrow();
    pqxx::nontransaction w(*c);  // one statement: no BEGIN/COMMIT round trips
    return w.exec1("SELECT COALESCE(MAX(version), 0) FROM schema_version")[0].as<int>();
}

void PostgresJobStore::insert_job(const JobRow& job, uint32_t frame_count) {
    auto c = pool_.borrow();
    pqxx::work w(*c);
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
    auto c = pool_.borrow();
    pqxx::nontransaction w(*c);  // one statement: no BEGIN/COMMIT round trips
    w.exec_params("UPDATE jobs SET priority = $2 WHERE id = $1", job_id, priority);
    w.commit();
}

void PostgresJobStore::update_job_state(const std::string& job_id, int state,
                                        const std::string& error, int64_t finished_ms) {
    auto c = pool_.borrow();
    pqxx::nontransaction w(*c);  // one statement: no BEGIN/COMMIT round trips
    w.exec_params(
        "UPDATE jobs SET state = $2, error = $3, "
        "finished_ms = CASE WHEN $4::BIGINT > 0 THEN $4::BIGINT ELSE finished_ms END "
        "WHERE id = $1",
        job_id, state, error, finished_ms);
    w.commit();
}

void PostgresJobStore::update_frame(const std::string& job_id, uint32_t frame, bool done,
                                    double elapsed) {
    auto c = pool_.borrow();
    pqxx::nontransaction w(*c);  // one statement: no BEGIN/COMMIT round trips
    w.exec_params("UPDATE frames SET done = $3, elapsed = $4 WHERE job_id = $1 AND idx = $2",
                  job_id, int64_t(frame), done ? 1 : 0, elapsed);
    w.commit();
}

std::vector<JobRow> PostgresJobStore::load_jobs() {
    auto c = pool_.borrow();
    pqxx::nontransaction w(*c);  // one statement: no BEGIN/COMMIT round trips
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
    auto c = pool_.borrow();
    pqxx::nontransaction w(*c);  // one statement: no BEGIN/COMMIT round trips
    pqxx::result rows = w.exec_params(
        "SELECT idx, done, elapsed FROM frames WHERE job_id = $1 ORDER BY idx", job_id);
    std::vector<FrameRow> out;
    for (const pqxx::row& row : rows)
        out.push_back({uint32_t(row[0].as<int64_t>()), row[1].as<int>() != 0, row[2].as<double>()});
    return out;
}

int64_t PostgresJobStore::max_sequence() {
    auto c = pool_.borrow();
    pqxx::nontransaction w(*c);  // one statement: no BEGIN/COMMIT round trips
    return w.exec1("SELECT COALESCE(MAX(seq), 0) FROM jobs")[0].as<int64_t>();
}

void PostgresJobStore::add_merged_range(const std::string& job_id, uint32_t frame, Range range) {
    auto c = pool_.borrow();
    pqxx::nontransaction w(*c);  // one statement: no BEGIN/COMMIT round trips
    w.exec_params(
        "INSERT INTO merged_ranges (job_id, frame, first, end_) VALUES ($1, $2, $3, $4) "
        "ON CONFLICT (job_id, frame, first) DO UPDATE SET end_ = EXCLUDED.end_",
        job_id, int64_t(frame), i64(range.first), i64(range.end));
    w.commit();
}

void PostgresJobStore::set_merged_ranges(const std::string& job_id, uint32_t frame,
                                         const std::vector<Range>& ranges) {
    auto c = pool_.borrow();
    pqxx::work w(*c);
    replace_ranges(w, job_id, frame, ranges);
    w.commit();
}

std::vector<Range> PostgresJobStore::merged_ranges(const std::string& job_id, uint32_t frame) {
    auto c = pool_.borrow();
    pqxx::nontransaction w(*c);  // one statement: no BEGIN/COMMIT round trips
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
    auto c = pool_.borrow();
    pqxx::work w(*c);
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
    auto c = pool_.borrow();
    pqxx::nontransaction w(*c);  // one statement: no BEGIN/COMMIT round trips
    w.exec_params(
        "INSERT INTO assets (sha256, size, added_ms) "
        "VALUES ($1, $2, (EXTRACT(EPOCH FROM now()) * 1000)::BIGINT) "
        "ON CONFLICT (sha256) DO NOTHING",
        sha256, i64(size));
    w.commit();
}

void PostgresJobStore::delete_assets(const std::vector<std::string>& assets) {
    auto c = pool_.borrow();
    pqxx::work w(*c);
    delete_asset_rows(w, assets);
    w.commit();
}

void PostgresJobStore::delete_job(const std::string& job_id,
                                  const std::vector<std::string>& assets) {
    auto c = pool_.borrow();
    pqxx::work w(*c);
    for (const char* sql :
         {"DELETE FROM jobs WHERE id = $1", "DELETE FROM frames WHERE job_id = $1",
          "DELETE FROM merged_ranges WHERE job_id = $1", "DELETE FROM leases WHERE job_id = $1"})
        w.exec_params(sql, job_id);
    delete_asset_rows(w, assets);
    w.commit();
}

void PostgresJobStore::insert_lease(const std::string& lease_id, const std::string& worker_id,
                                    const std::string& job_id, uint32_t frame, Range range) {
    auto c = pool_.borrow();
    pqxx::nontransaction w(*c);  // one statement: no BEGIN/COMMIT round trips
    w.exec_prepared("insert_lease", lease_id, worker_id, job_id, int64_t(frame), i64(range.first),
                    i64(range.end));
    w.commit();
}

bool PostgresJobStore::claim_lease(const LeaseRow& lease) {
    auto c = pool_.borrow();
    pqxx::nontransaction w(*c);
    // One round trip: render_claim_lease (migration 5) locks the frame's row (SELECT ... FOR
    // UPDATE), so a claim on the same frame from any connection waits until this statement's
    // transaction ends and then, its overlap check taking a new snapshot, finds this lease.
    return w
        .exec_params1("SELECT render_claim_lease($1, $2, $3, $4, $5, $6)", lease.lease_id,
                      lease.worker_id, lease.job_id, int64_t(lease.frame), i64(lease.range.first),
                      i64(lease.range.end))[0]
        .as<bool>();
}

void PostgresJobStore::delete_lease(const std::string& lease_id) {
    auto c = pool_.borrow();
    pqxx::nontransaction w(*c);  // one statement: no BEGIN/COMMIT round trips
    w.exec_prepared("delete_lease", lease_id);
    w.commit();
}

void PostgresJobStore::delete_leases(const std::vector<std::string>& lease_ids) {
    if (lease_ids.empty()) return;
    auto c = pool_.borrow();
    pqxx::nontransaction w(*c);  // one statement: no BEGIN/COMMIT round trips
    w.exec_params("DELETE FROM leases WHERE lease_id = ANY($1::TEXT[])", text_array(lease_ids));
    w.commit();
}

std::vector<LeaseRow> PostgresJobStore::load_leases() {
    auto c = pool_.borrow();
    pqxx::nontransaction w(*c);  // one statement: no BEGIN/COMMIT round trips
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
    auto c = pool_.borrow();
    pqxx::nontransaction w(*c);  // one statement: no BEGIN/COMMIT round trips
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
    auto c = pool_.borrow();
    pqxx::nontransaction w(*c);  // one statement: no BEGIN/COMMIT round trips
    pqxx::result r = w.exec("DELETE FROM leases");
    w.commit();
    return int(r.affected_rows());
}

int PostgresJobStore::clear_job_leases(const std::string& job_id) {
    auto c = pool_.borrow();
    pqxx::nontransaction w(*c);  // one statement: no BEGIN/COMMIT round trips
    pqxx::result r = w.exec_params("DELETE FROM leases WHERE job_id = $1", job_id);
    w.commit();
    return int(r.affected_rows());
}

std::optional<int64_t> PostgresJobStore::take_job(const std::string& job_id,
                                                  const std::string& server,
                                                  const std::string& address, int64_t hold_ms) {
    auto c = pool_.borrow();
    pqxx::nontransaction w(*c);  // one statement: no BEGIN/COMMIT round trips
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
    auto c = pool_.borrow();
    pqxx::nontransaction w(*c);  // one statement: no BEGIN/COMMIT round trips
    pqxx::result r = w.exec_params("UPDATE jobs SET owner_until_ms = " RENDER_PG_NOW_MS
                                   " + $4 WHERE id = $1 AND owner = $2 AND owner_epoch = $3",
                                   job_id, server, epoch, hold_ms);
    w.commit();
    return r.affected_rows() == 1;
}

void PostgresJobStore::release_job(const std::string& job_id, const std::string& server,
                                   int64_t epoch) {
    auto c = pool_.borrow();
    pqxx::nontransaction w(*c);  // one statement: no BEGIN/COMMIT round trips
    w.exec_params(
        "UPDATE jobs SET owner = NULL, owner_until_ms = NULL WHERE id = $1 AND owner = $2 AND "
        "owner_epoch = $3",
        job_id, server, epoch);
    w.commit();
}

void PostgresJobStore::record_workers(const std::string& server,
                                      const std::vector<FarmWorkerRow>& workers,
                                      int64_t forget_ms) {
    auto c = pool_.borrow();
    pqxx::nontransaction w(*c);
    // One statement: the upsert and the deletion of this server's departed workers and of
    // every long-silent server's rows (both parts see the rows as they were before it).
    w.exec_params(
        "WITH up AS (INSERT INTO farm_workers (worker_id, server, server_address, host, threads, "
        "version, seen_ms, iterations_per_second, samples_per_second, rays_per_second, "
        "recorded_ms) SELECT w, $1, a, h, t, v, s, i, sp, r, " RENDER_PG_NOW_MS
        " FROM unnest($2::TEXT[], $3::TEXT[], $4::TEXT[], $5::BIGINT[], $6::TEXT[], $7::BIGINT[], "
        "$8::DOUBLE PRECISION[], $9::DOUBLE PRECISION[], $10::DOUBLE PRECISION[]) "
        "AS x(w, a, h, t, v, s, i, sp, r) "
        "ON CONFLICT (server, worker_id) DO UPDATE SET server_address = EXCLUDED.server_address, "
        "host = EXCLUDED.host, threads = EXCLUDED.threads, version = EXCLUDED.version, "
        "seen_ms = EXCLUDED.seen_ms, iterations_per_second = EXCLUDED.iterations_per_second, "
        "samples_per_second = EXCLUDED.samples_per_second, "
        "rays_per_second = EXCLUDED.rays_per_second, recorded_ms = EXCLUDED.recorded_ms) "
        "DELETE FROM farm_workers WHERE (server = $1 AND NOT (worker_id = ANY($2::TEXT[]))) OR "
        "recorded_ms < " RENDER_PG_NOW_MS " - $11",
        server, text_column(workers, [](const FarmWorkerRow& r) { return r.worker_id; }),
        text_column(workers, [](const FarmWorkerRow& r) { return r.server_address; }),
        text_column(workers, [](const FarmWorkerRow& r) { return r.host; }),
        number_array(workers, [](const FarmWorkerRow& r) { return int64_t(r.threads); }),
        text_column(workers, [](const FarmWorkerRow& r) { return r.version; }),
        number_array(workers, [](const FarmWorkerRow& r) { return r.seen_unix_ms; }),
        number_array(workers, [](const FarmWorkerRow& r) { return r.iterations_per_second; }),
        number_array(workers, [](const FarmWorkerRow& r) { return r.samples_per_second; }),
        number_array(workers, [](const FarmWorkerRow& r) { return r.rays_per_second; }), forget_ms);
    w.commit();
}

std::vector<FarmWorkerRow> PostgresJobStore::load_workers(int64_t max_age_ms) {
    auto c = pool_.borrow();
    pqxx::nontransaction w(*c);
    pqxx::result rows = w.exec_params(
        "SELECT worker_id, server, COALESCE(server_address, ''), COALESCE(host, ''), "
        "COALESCE(threads, 0), COALESCE(version, ''), COALESCE(seen_ms, 0), "
        "COALESCE(iterations_per_second, 0), COALESCE(samples_per_second, 0), "
        "COALESCE(rays_per_second, 0) FROM farm_workers WHERE recorded_ms >= " RENDER_PG_NOW_MS
        " - $1 ORDER BY server, worker_id",
        max_age_ms);
    std::vector<FarmWorkerRow> out;
    for (const pqxx::row& row : rows) {
        FarmWorkerRow r;
        r.worker_id = row[0].as<std::string>();
        r.server = row[1].as<std::string>();
        r.server_address = row[2].as<std::string>();
        r.host = row[3].as<std::string>();
        r.threads = uint32_t(row[4].as<int64_t>());
        r.version = row[5].as<std::string>();
        r.seen_unix_ms = row[6].as<int64_t>();
        r.iterations_per_second = row[7].as<double>();
        r.samples_per_second = row[8].as<double>();
        r.rays_per_second = row[9].as<double>();
        out.push_back(std::move(r));
    }
    return out;
}

std::optional<StoreConnectionStats> PostgresJobStore::connection_stats() const {
    const PgConnectionPool::Stats s = pool_.stats();
    return StoreConnectionStats{s.size,     s.in_use, s.connections_made,
                                s.borrowed, s.waited, s.wait_seconds};
}

}  // namespace render::server
