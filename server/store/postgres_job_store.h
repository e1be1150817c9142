#pragma once

// The job store in a PostgreSQL database (libpqxx), for a farm whose queue outlives one machine
// and is shared by several servers (docs/design/job-store.md). A pool of connections
// (server/store/pg_connection_pool.h), one per operation at a time; claim_lease locks the
// frame's row (SELECT ... FOR UPDATE), so every connection, of this server or another, sees
// one consistent set of leases.

#include <memory>
#include <string>

#include "server/job_store.h"
#include "server/store/pg_connection_pool.h"

namespace render::server {

class PostgresJobStore final : public JobStore {
  public:
    // `url`: a libpq connection URI (postgresql://user@host:port/database?...). Connects and
    // migrates the schema to kJobStoreSchemaVersion (several servers starting at once migrate
    // one after the other: an advisory lock serialises them). `connections`: the pool's size
    // (server --store-connections).
    explicit PostgresJobStore(const std::string& url,
                              size_t connections = kDefaultStoreConnections);
    ~PostgresJobStore() override;
    PostgresJobStore(const PostgresJobStore&) = delete;
    PostgresJobStore& operator=(const PostgresJobStore&) = delete;

    int schema_version() override;

    void insert_job(const JobRow& job, uint32_t frame_count) override;
    void update_job_priority(const std::string& job_id, int priority) override;
    void update_job_state(const std::string& job_id, int state, const std::string& error,
                          int64_t finished_ms = 0) override;
    void update_frame(const std::string& job_id, uint32_t frame, bool done,
                      double elapsed) override;
    std::vector<JobRow> load_jobs() override;
    std::vector<FrameRow> load_frames(const std::string& job_id) override;
    int64_t max_sequence() override;

    void add_merged_range(const std::string& job_id, uint32_t frame, Range range) override;
    void set_merged_ranges(const std::string& job_id, uint32_t frame,
                           const std::vector<Range>& ranges) override;
    std::vector<Range> merged_ranges(const std::string& job_id, uint32_t frame) override;
    void save_frame(const std::string& job_id, uint32_t frame, const std::vector<Range>& ranges,
                    bool done, double elapsed, int64_t hold_epoch) override;

    void add_asset(const std::string& sha256, uint64_t size) override;
    void delete_assets(const std::vector<std::string>& assets) override;
    void delete_job(const std::string& job_id, const std::vector<std::string>& assets) override;

    void insert_lease(const std::string& lease_id, const std::string& worker_id,
                      const std::string& job_id, uint32_t frame, Range range) override;
    bool claim_lease(const LeaseRow& lease) override;
    void delete_lease(const std::string& lease_id) override;
    void delete_leases(const std::vector<std::string>& lease_ids) override;
    std::vector<LeaseRow> load_leases() override;
    std::optional<LeaseRow> find_lease(const std::string& lease_id) override;
    int clear_leases() override;
    int clear_job_leases(const std::string& job_id) override;

    std::optional<int64_t> take_job(const std::string& job_id, const std::string& server,
                                    const std::string& address, int64_t hold_ms) override;
    bool renew_job(const std::string& job_id, const std::string& server, int64_t epoch,
                   int64_t hold_ms) override;
    void release_job(const std::string& job_id, const std::string& server, int64_t epoch) override;
    bool shared() const override { return true; }

    void record_workers(const std::string& server, const std::vector<FarmWorkerRow>& workers,
                        int64_t forget_ms) override;
    std::vector<FarmWorkerRow> load_workers(int64_t max_age_ms) override;

    // The pool's figures (metrics: where the Lease and Report paths wait).
    std::optional<StoreConnectionStats> connection_stats() const override;

  private:
    void migrate();
    PgConnectionPool pool_;
};

}  // namespace render::server
