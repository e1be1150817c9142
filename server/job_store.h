#pragma once

// The persistent job queue: jobs, frames, assets, outstanding leases and merged ranges, behind
// one interface with two backends (docs/design/job-store.md): SQLite (server/store/
// sqlite_job_store.h, the embedded default) and PostgreSQL (server/store/
// postgres_job_store.h). open_job_store (server/store/open_job_store.h) picks one by location.
// Every implementation is thread-safe and throws std::runtime_error with the database's message
// on failure; each brings its schema to kJobStoreSchemaVersion when opened.

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "server/interval_set.h"

namespace render::server {

// The schema's version; both backends apply the same numbered migrations (docs/design/
// job-store.md, "Migrations"). A store of a newer version is refused.
inline constexpr int kJobStoreSchemaVersion = 5;

// The PostgreSQL store's connections per server unless server --store-connections says
// otherwise (docs/design/job-store.md, "Connections").
inline constexpr size_t kDefaultStoreConnections = 8;

// Which server holds a job's sums while it renders (docs/design/job-store.md, "Several
// servers, one farm"): a hold with an expiry on the database's clock and an epoch that every
// new holder increments, so that a server whose hold lapsed and was taken knows it.
struct JobOwner {
    std::string server;   // the holder's id; empty: nobody holds the job
    std::string address;  // where the holder serves (for a client's or worker's hint)
    int64_t epoch = 0;
    bool live = false;  // held, and the hold has not run out
};

// A fenced write (save_frame with a hold epoch) found the hold taken by another server or
// released: nothing was written.
struct HoldLost : std::runtime_error {
    using std::runtime_error::runtime_error;
};

struct JobRow {
    std::string id;
    int64_t sequence = 0;
    std::string name;
    int state = 1;
    int priority = 0;
    std::string request;  // serialized render.v1.SubmitJobRequest (settings resolved)
    int width = 0, height = 0;
    std::string error;
    int64_t submitted_unix_ms = 0;
    // When the job reached DONE, FAILED or CANCELLED (0: not yet, or a store written before
    // this column existed), for the retention rule (server --retain-finished).
    int64_t finished_unix_ms = 0;
    JobOwner owner;  // read by load_jobs; insert_job stores the job unheld
};

struct FrameRow {
    uint32_t index = 0;
    bool done = false;
    double elapsed_seconds = 0;
};

// One outstanding lease as the store records it.
struct LeaseRow {
    std::string lease_id;
    std::string worker_id;
    std::string job_id;
    uint32_t frame = 0;
    Range range;
};

// One worker as a server of a shared store last saw it (docs/design/job-store.md, "The farm's
// workers"): every server's dashboard lists the whole farm from these rows.
struct FarmWorkerRow {
    std::string worker_id;
    std::string server;          // the id of the server it calls
    std::string server_address;  // that server's --advertise
    std::string host;
    uint32_t threads = 0;
    std::string version;
    int64_t seen_unix_ms = 0;  // when that server last heard from it (its clock)
    double iterations_per_second = 0;
    double samples_per_second = 0;
    double rays_per_second = 0;
};

// A pooled store's connections, for metrics (where the Lease and Report paths wait).
struct StoreConnectionStats {
    size_t size = 0;
    size_t in_use = 0;
    uint64_t connections_made = 0;
    uint64_t borrowed = 0;
    uint64_t waited = 0;
    double wait_seconds = 0;
};

class JobStore {
  public:
    virtual ~JobStore() = default;

    // The schema version the store is at (kJobStoreSchemaVersion once opened).
    virtual int schema_version() = 0;

    virtual void insert_job(const JobRow& job, uint32_t frame_count) = 0;
    virtual void update_job_priority(const std::string& job_id, int priority) = 0;
    // `finished_ms`: when a terminal state was reached (0 leaves the recorded time).
    virtual void update_job_state(const std::string& job_id, int state, const std::string& error,
                                  int64_t finished_ms = 0) = 0;
    virtual void update_frame(const std::string& job_id, uint32_t frame, bool done,
                              double elapsed) = 0;
    virtual std::vector<JobRow> load_jobs() = 0;
    virtual std::vector<FrameRow> load_frames(const std::string& job_id) = 0;
    virtual int64_t max_sequence() = 0;

    virtual void add_merged_range(const std::string& job_id, uint32_t frame, Range range) = 0;
    // Replaces a frame's merged ranges (to agree with its checkpoint after a restart).
    virtual void set_merged_ranges(const std::string& job_id, uint32_t frame,
                                   const std::vector<Range>& ranges) = 0;
    virtual std::vector<Range> merged_ranges(const std::string& job_id, uint32_t frame) = 0;
    // In one transaction: the frame's merged ranges become `ranges` (what its checkpoint, or
    // its finished EXR, holds) and its row gets `done` and `elapsed`. `hold_epoch` 0: written
    // (one server). Otherwise the write fence of a shared store (docs/design/job-store.md,
    // "The write fence"): written only while the job's hold is still of that epoch, the job's
    // row locked meanwhile so that no take_job passes in between; else HoldLost is thrown
    // and nothing is written.
    virtual void save_frame(const std::string& job_id, uint32_t frame,
                            const std::vector<Range>& ranges, bool done, double elapsed,
                            int64_t hold_epoch) = 0;

    virtual void add_asset(const std::string& sha256, uint64_t size) = 0;
    // The rows of assets removed from the asset store with no job (never submitted, or their
    // jobs deleted), in one transaction.
    virtual void delete_assets(const std::vector<std::string>& assets) = 0;
    // In one transaction: the job's row, its frames, merged ranges and leases, and the rows of
    // `assets` (those the job alone referenced, removed from the asset store).
    virtual void delete_job(const std::string& job_id, const std::vector<std::string>& assets) = 0;

    // Records a lease the caller's scheduler granted (one server: its scheduler alone hands
    // out ranges, so no check is needed; this is the Lease path's one write).
    virtual void insert_lease(const std::string& lease_id, const std::string& worker_id,
                              const std::string& job_id, uint32_t frame, Range range) = 0;
    // Records `lease` only if its range overlaps no outstanding lease and no merged range of
    // its frame, atomically against every other connection to the same database: the frame's
    // row is locked for the check (docs/design/job-store.md, "Leasing"), so two servers on
    // one database never hold the same iterations. False when it overlaps (nothing written).
    virtual bool claim_lease(const LeaseRow& lease) = 0;
    virtual void delete_lease(const std::string& lease_id) = 0;
    // The rows of reported leases, many at once (one statement on PostgreSQL, one transaction
    // on SQLite): the server deletes them in batches off the Report path (JobManager::tick).
    virtual void delete_leases(const std::vector<std::string>& lease_ids) = 0;
    virtual std::vector<LeaseRow> load_leases() = 0;
    // One outstanding lease by its id (a report that reached a server which did not grant it
    // is forwarded to the job's holder: docs/design/job-store.md).
    virtual std::optional<LeaseRow> find_lease(const std::string& lease_id) = 0;
    // Voids every lease of a previous run; returns how many there were.
    virtual int clear_leases() = 0;
    // Voids the job's leases (a new holder voids its predecessor's); returns how many.
    virtual int clear_job_leases(const std::string& job_id) = 0;

    // --- holding a job's sums (several servers on one database) ---
    // Takes the job for `server` when nobody holds it or the hold ran out (on the database's
    // clock), for `hold_ms`: returns the new epoch, or nothing when another server holds it.
    // Atomic: of servers taking one job at once, one succeeds.
    virtual std::optional<int64_t> take_job(const std::string& job_id, const std::string& server,
                                            const std::string& address, int64_t hold_ms) = 0;
    // Extends the hold `server` took with `epoch` by `hold_ms` from now; false when another
    // server has taken the job since (a hold that ran out but was not taken is extended).
    virtual bool renew_job(const std::string& job_id, const std::string& server, int64_t epoch,
                           int64_t hold_ms) = 0;
    // Gives the hold up at once (a server stopping): another server may take the job now.
    virtual void release_job(const std::string& job_id, const std::string& server,
                             int64_t epoch) = 0;
    // Whether several servers may share this store (PostgreSQL): the server then holds jobs
    // before it merges them and leases through claim_lease.
    virtual bool shared() const = 0;

    // --- the farm's workers (several servers on one database) ---
    // `server`'s workers become `workers` (its earlier rows not among them go), stamped with
    // the database's time; rows of any server recorded more than `forget_ms` ago are removed
    // (a server that died). One statement on PostgreSQL.
    virtual void record_workers(const std::string& server,
                                const std::vector<FarmWorkerRow>& workers, int64_t forget_ms) = 0;
    // The rows of every server recorded within `max_age_ms` (on the database's clock),
    // ordered by server and worker.
    virtual std::vector<FarmWorkerRow> load_workers(int64_t max_age_ms) = 0;

    // The connection pool's figures; nothing for a store without one (SQLite).
    virtual std::optional<StoreConnectionStats> connection_stats() const { return std::nullopt; }
};

}  // namespace render::server
