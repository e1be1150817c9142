#pragma once

// The job store in one SQLite database file (WAL): the embedded default, one server per file
// (docs/design/job-store.md). One connection behind a mutex.

#include <filesystem>
#include <mutex>

#include "server/job_store.h"

struct sqlite3;
struct sqlite3_stmt;

namespace render::server {

class SqliteJobStore final : public JobStore {
  public:
    // Opens (or creates) the database and migrates it to kJobStoreSchemaVersion.
    explicit SqliteJobStore(const std::filesystem::path& database);
    ~SqliteJobStore() override;
    SqliteJobStore(const SqliteJobStore&) = delete;
    SqliteJobStore& operator=(const SqliteJobStore&) = delete;

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
    bool shared() const override { return false; }
    void record_workers(const std::string& server, const std::vector<FarmWorkerRow>& workers,
                        int64_t forget_ms) override;
    std::vector<FarmWorkerRow> load_workers(int64_t max_age_ms) override;

  private:
    void exec(const char* sql);
    // Brings the schema to kJobStoreSchemaVersion, one migration per transaction.
    void migrate();
    void apply_migration(int version);
    int read_schema_version();
    // Records one merged range; the caller holds mu_.
    void insert_merged_range(const std::string& job_id, uint32_t frame, Range range);
    // The rows of `assets`, inside the caller's transaction (delete_job, delete_assets).
    void delete_asset_rows(const std::vector<std::string>& assets);
    // A frame's merged ranges replaced by `ranges`, inside the caller's transaction.
    void replace_merged_ranges(const std::string& job_id, uint32_t frame,
                               const std::vector<Range>& ranges);
    sqlite3* db_ = nullptr;
    // Prepared once: a lease row is written at every Lease and deleted at every Report.
    sqlite3_stmt* insert_lease_ = nullptr;
    sqlite3_stmt* delete_lease_ = nullptr;
    std::mutex mu_;
};

}  // namespace render::server
