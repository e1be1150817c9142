#pragma once

// The persistent job queue: one SQLite database (WAL) with jobs, frames, assets, outstanding
// leases and merged ranges. Thread-safe (one connection behind a mutex). Throws
// std::runtime_error with SQLite's message on failure.

#include <cstdint>
#include <filesystem>
#include <mutex>
#include <string>
#include <vector>

#include "server/interval_set.h"

struct sqlite3;
struct sqlite3_stmt;

namespace render::server {

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
};

struct FrameRow {
    uint32_t index = 0;
    bool done = false;
    double elapsed_seconds = 0;
};

class JobStore {
  public:
    explicit JobStore(const std::filesystem::path& database);
    ~JobStore();
    JobStore(const JobStore&) = delete;
    JobStore& operator=(const JobStore&) = delete;

    void insert_job(const JobRow& job, uint32_t frame_count);
    void update_job_priority(const std::string& job_id, int priority);
    // `finished_ms`: when a terminal state was reached (0 leaves the recorded time).
    void update_job_state(const std::string& job_id, int state, const std::string& error,
                          int64_t finished_ms = 0);
    void update_frame(const std::string& job_id, uint32_t frame, bool done, double elapsed);
    std::vector<JobRow> load_jobs();
    std::vector<FrameRow> load_frames(const std::string& job_id);
    int64_t max_sequence();

    void add_merged_range(const std::string& job_id, uint32_t frame, Range range);
    // Replaces a frame's merged ranges (to agree with its checkpoint after a restart).
    void set_merged_ranges(const std::string& job_id, uint32_t frame,
                           const std::vector<Range>& ranges);
    std::vector<Range> merged_ranges(const std::string& job_id, uint32_t frame);
    // In one transaction: the frame's merged ranges become `ranges` (what its checkpoint, or
    // its finished EXR, holds) and its row gets `done` and `elapsed`.
    void save_frame(const std::string& job_id, uint32_t frame, const std::vector<Range>& ranges,
                    bool done, double elapsed);

    void add_asset(const std::string& sha256, uint64_t size);
    // The rows of assets removed from the asset store with no job (never submitted, or their
    // jobs deleted), in one transaction.
    void delete_assets(const std::vector<std::string>& assets);
    // In one transaction: the job's row, its frames, merged ranges and leases, and the rows of
    // `assets` (those the job alone referenced, removed from the asset store).
    void delete_job(const std::string& job_id, const std::vector<std::string>& assets);

    void insert_lease(const std::string& lease_id, const std::string& worker_id,
                      const std::string& job_id, uint32_t frame, Range range);
    void delete_lease(const std::string& lease_id);
    // Voids every lease of a previous run; returns how many there were.
    int clear_leases();

  private:
    void exec(const char* sql);
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
