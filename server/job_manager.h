#pragma once

// The server's state behind both gRPC services: jobs (persisted in the JobStore), the
// scheduler's lease table, the frames' sums and checkpoints, finished EXRs, workers.
// Thread-safe. Returns grpc::Status with precise codes for bad requests.
//
// The manager holds the locks and wires the parts together; each part is its own file:
// submission checking (submission_check.h), the failure policy (failure_policy.h), the
// workers (worker_registry.h), frames and checkpoints (frame_files.h). Its own definitions
// are split by concern: job_manager.cpp (jobs: restore, submit, state), job_manager_workers.cpp
// (the worker protocol and failures), job_manager_reports.cpp (merging reports),
// job_manager_frames.cpp (checkpoints, finished frames, previews), job_manager_housekeeping.cpp
// (deletion, retention, the asset sweep) and job_manager_views.cpp (what clients, the
// dashboard and metrics see).

#include <grpcpp/grpcpp.h>

#include <atomic>
#include <filesystem>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <span>
#include <string>
#include <vector>

#include "core/render/adaptive_maps.h"
#include "render.pb.h"
#include "server/accumulator.h"
#include "server/asset_store.h"
#include "server/failure_policy.h"
#include "server/frame_files.h"
#include "server/job_store.h"
#include "server/metrics.h"
#include "server/scheduler.h"
#include "server/stream_guard.h"
#include "server/validation.h"
#include "server/worker_registry.h"

namespace render::server {

// How often the server's thread calls JobManager::tick() (its housekeeping, the expiry sweep
// and, on a shared store, the sync's check): the pause between two ticks.
inline constexpr double kTickSeconds = 0.25;

namespace v1 = ::render::v1;

struct ServerOptions {
    // The folder of assets, checkpoints, results and spooled reports, and of the SQLite
    // database (render.db) unless `database` names another store.
    std::filesystem::path store;
    // A store URL (server/store/open_job_store.h: postgresql://... or sqlite:FILE); empty:
    // SQLite in store/render.db.
    std::string database = {};
    double lease_timeout_seconds = 30;
    double heartbeat_seconds = 2;
    double target_lease_seconds = 3;
    // A lease of several iterations lasts at most this long (SchedulerOptions).
    double max_lease_seconds = 30;
    // A frame's merged sums are written to its checkpoint (and the job store records the
    // ranges the checkpoint holds) by tick() at most every checkpoint_seconds, counted from the
    // frame's first merge in this run, or 50 times the last checkpoint's duration if longer;
    // on SIGTERM (checkpoint_all) at once. 0: by every report. A crash loses what merged after
    // the last checkpoint: those ranges are leased again.
    double checkpoint_seconds = 30;
    // SubmitJob loads every frame's scene; an animation whose loads would take longer than this
    // (estimated from the frames loaded so far) is refused with RESOURCE_EXHAUSTED.
    double submit_validation_seconds = 120;
    // The assets' limits: a job's bundle in all (and so any one asset), and every asset the
    // store keeps (uploads reserve their size first). Past either, RESOURCE_EXHAUSTED naming it.
    uint64_t max_job_assets = kDefaultMaxJobAssets;
    uint64_t max_store_size = kDefaultMaxStoreSize;
    // The bulk streams: each of clients' (UploadAsset, FetchResult) and workers' (FetchAsset)
    // at most max_streams open at once, each cancelled after idle_seconds without a chunk.
    StreamLimits streams{};
    // A job refused for memory by every live worker (each refused it, or is known to have a
    // smaller limit than it needs) FAILS once that has lasted this long (docs/guide/service.md).
    double memory_wait_seconds = 300;
    // Retention (docs/guide/service.md, "Deleting jobs"): a finished, failed or cancelled job is
    // deleted, as DeleteJob deletes it, once it finished this long ago; 0 keeps jobs until a
    // client deletes them. Checked at every tick() (a scan of the jobs in memory).
    double retain_finished_seconds = 0;
    // An uploaded asset that no job references is removed once it was last uploaded or named
    // in a HasAssets request this long ago (a client uploaded and never submitted); 0 never.
    // Swept by tick() every quarter of this (0.5 s to 60 s).
    double unreferenced_asset_seconds = 86400;
    // For tests and measurements (--report-delay): a report whose values are received waits
    // this long before it is merged, as over a slow network or on a busy server; a worker that
    // disconnects meanwhile cancels it (it is not merged, and its lease expires).
    double report_delay_seconds = 0;
    // A report whose values are at least this many bytes is spooled to a file in the store's
    // spool folder while it arrives, not held in memory (server/report_values.h): a running
    // frame then costs its sums plus blocks rather than its sums plus a whole report. The
    // default spools a 1920x1080 report of several iterations (100 MB) and keeps a 1280x720
    // one (44 MB) in memory; 0 spools every report, SIZE_MAX none.
    uint64_t spool_reports_above = uint64_t(64) << 20;
    // Several servers on one shared store (PostgreSQL; docs/design/job-store.md, "Several
    // servers, one farm"): the address this server is reached at, recorded with the jobs it
    // holds; and how long its hold of a job's sums lasts unrenewed (renewed every
    // hold_seconds / 4) before another server takes the job over from its last checkpoint.
    std::string advertise_address = {};
    double hold_seconds = 10;
    // The PostgreSQL store's connections (docs/design/job-store.md, "Connections").
    size_t store_connections = kDefaultStoreConnections;
};

class JobManager {
  public:
    explicit JobManager(ServerOptions options, Scheduler::ClockFn clock = SteadyClock::now);
    ~JobManager();

    // --- public API ---
    grpc::Status submit(const v1::SubmitJobRequest& request, v1::Job* job);
    grpc::Status get(const std::string& job_id, v1::Job* job);
    void list(v1::ListJobsReply* reply);
    grpc::Status cancel(const std::string& job_id, v1::Job* job);
    // Deletes a finished, failed or cancelled job (FAILED_PRECONDITION otherwise: cancel it
    // first): its rows, scene folder, checkpoints and results, and the assets of its bundle
    // that no other job references and no submit in progress names (the store's size goes
    // down by theirs). An asset uploaded but not yet in any submitted job is kept (the asset
    // sweep removes it after unreferenced_asset_seconds).
    // `reason` goes to the log line ("request", or "retention" for the rule above).
    grpc::Status delete_job(const std::string& job_id, v1::DeleteJobReply* reply,
                            const char* reason = "request");
    // The EXR to stream for FetchResult; `temporary` files (previews) are deleted by the caller.
    grpc::Status result_file(const v1::FetchResultRequest& request, std::filesystem::path* file,
                             bool* temporary);
    void cluster_status(v1::ClusterStatusReply* reply);
    // Sets a job's priority (higher first); FAILED_PRECONDITION for a finished job.
    grpc::Status set_priority(const std::string& job_id, int priority, v1::Job* job);
    // The current mean image of a frame (the result once it is done), for the dashboard's
    // preview; FAILED_PRECONDITION while nothing has merged.
    grpc::Status preview_image(const std::string& job_id, uint32_t frame, Image* image);
    // The frame's per-pixel variance and sample counts, for the dashboard's maps beside the
    // preview (core/render/adaptive_maps.h; job_manager_maps.cpp): from the merged sums while the
    // frame renders, from the result EXR's layers once it is done.
    grpc::Status pixel_maps(const std::string& job_id, uint32_t frame, PixelMaps* maps);
    // A frame's estimated relative error after each merged report, against its render time.
    using ErrorPoint = server::ErrorPoint;
    grpc::Status error_history(const std::string& job_id, uint32_t frame,
                               std::vector<ErrorPoint>* points);
    // The Prometheus text exposition of the server's metrics (server/metrics.h).
    std::string metrics_text();
    // The farm as this server sees it (several servers on one store; the dashboard's
    // /api/farm): JSON {"shared", "self", "servers": [{"address", "jobs_held", "self"}],
    // "jobs_unheld"}, the holds as the last sync read them from the store.
    std::string farm_json();
    ServerMetrics& metrics() { return metrics_; }
    // Lists the missing assets; the present ones are touched (the client is about to submit a
    // job naming them: the asset sweep's grace period starts again).
    void has_assets(const v1::HasAssetsRequest& request, v1::HasAssetsReply* reply);
    // Records an uploaded asset (and touches it, on the manager's clock).
    void asset_added(const std::string& sha256, uint64_t size);

    // --- worker protocol ---
    void register_worker(const v1::RegisterWorkerRequest& request, v1::RegisterWorkerReply* reply);
    grpc::Status lease(const v1::LeaseRequest& request, v1::LeaseReply* reply);
    grpc::Status heartbeat(const v1::HeartbeatRequest& request, v1::HeartbeatReply* reply);
    // The packed mask (service/mask_bits.h) of the adaptive round of the worker's lease
    // `lease_id` (FetchMask): NOT_FOUND for a lease unknown or not the worker's,
    // FAILED_PRECONDITION for one of round 0 or of a round that is over.
    grpc::Status fetch_mask(const v1::FetchMaskRequest& request, std::string* packed);
    // Checks a report's header before its values are read: `values` receives the number of
    // float64 values each of sum, odd_sum (unless the header omits it) and the job's technique
    // layers must have, `layers` how many layers follow the sums. `drop` is set (and OK returned)
    // for a late or duplicate report, which is answered merged=false.
    // `exact_words` receives the int64 words of an adaptive job's exact sums that follow the
    // layers (0 for another job; proto/render.proto, ReportHeader.exact_sums).
    grpc::Status check_report(const v1::ReportHeader& header, size_t* values, size_t* layers,
                              size_t* exact_words, bool* drop);
    // Merges a report's sums exactly once; `merged` false when dropped. `values`: sum, odd_sum
    // unless the header omits it, then the layers' sums (ReportValues), complete; they are
    // released once added, before a frame the report completes is written (memory).
    grpc::Status report(const v1::ReportHeader& header, ReportValues&& values, bool* merged);
    // Where large reports are spooled while they arrive (ServerOptions::spool_reports_above).
    std::filesystem::path report_spool_folder() const { return options_.store / "spool"; }
    // Reports of one job are received and merged one at a time: each holds a frame's whole
    // sums in memory until it is merged, so a job's memory stays its frames' sums plus one
    // report's, however many workers report at once. Blocks until the job of `lease_id` has no
    // other report in progress; the slot is released when the returned handle is destroyed
    // (null for a lease the server does not know: such a report is dropped unread).
    std::shared_ptr<void> report_slot(const std::string& lease_id);
    // The report stream of `lease_id` was cancelled for being idle (the worker stalled or went
    // away mid-report): the lease is voided and its range queued again at once, for another
    // worker; a later report of it is dropped (unknown lease), so nothing merges twice. Counted
    // as a lost lease of a worker that rendered (toward kMaxLostRenderingWorkers).
    void report_stream_idle(const std::string& lease_id);
    // The address this server's holds advertise (ServerOptions::advertise_address); set once
    // the listening port is bound, before tick() runs.
    void set_advertise_address(std::string address) {
        options_.advertise_address = std::move(address);
    }
    // Where a report this server cannot merge (it did not grant the lease) belongs: the
    // address of the live server that holds the lease's job, when the store is shared, still
    // records the lease and another server holds the job; empty otherwise (the report is
    // dropped). docs/design/job-store.md, "Reports reaching a non-holder". `max_value_bytes`
    // receives the size of the job's largest report's values (sum, odd_sum and layers).
    std::string report_holder(const std::string& lease_id, size_t* max_value_bytes);

    // Expires leases, closes time budgets, finishes complete frames, writes the checkpoints
    // that are due and applies the retention rule. Called periodically, from one thread (a
    // report does all but the checkpoints and the retention).
    void tick();
    // Writes the checkpoint of every frame that merged since its last one and saves the render
    // time of unfinished frames (SIGTERM).
    void checkpoint_all();
    // Deletes the rows of the leases reported since the last call, in one batch.
    void delete_reported_leases();

    AssetStore& assets() { return assets_; }
    // Clients' UploadAsset and FetchResult streams; workers' FetchAsset streams (apart, so
    // that clients cannot keep workers from their assets).
    StreamGuards& client_streams() { return client_streams_; }
    StreamGuards& worker_streams() { return worker_streams_; }
    // Workers' Report and clients' WatchJob streams: the same idle timeout, no count limit (a
    // report is one lease's; watchers have their own limit in JobServiceImpl).
    StreamGuards& long_streams() { return long_streams_; }
    const ServerOptions& options() const { return options_; }
    // This server's id in a shared store's holds (a new one at every start).
    const std::string& server_id() const { return server_id_; }
    // The ids of the jobs this server holds now (all unfinished ones on an unshared store).
    std::vector<std::string> held_jobs();

  private:
    struct JobData {
        JobRow row;
        v1::SubmitJobRequest request;  // settings resolved
        RenderSettings settings;       // what the request's complete options give (job_settings)
        std::vector<std::unique_ptr<FrameData>> frames;
        JobFailures failures;  // the poison and memory-wait bookkeeping (under mu_)
        std::mutex report_mu;  // held by the report being received and merged (report_slot)
        // On a shared store: whether this server holds the job's sums, and the epoch of its
        // hold (under mu_). Only the holder leases, merges, checkpoints and finishes a job;
        // the other servers show it as the store records it (job_manager_holds.cpp).
        bool held = false;
        int64_t hold_epoch = 0;
    };

    // --- jobs (job_manager.cpp) ---
    void restore();
    std::shared_ptr<JobData> find(const std::string& job_id);
    // The job holding frame `index`, or the status naming what is missing (takes mu_).
    grpc::Status find_frame(const std::string& job_id, uint32_t index,
                            std::shared_ptr<JobData>& job);
    bool known(const std::string& job_id);                                   // find under mu_
    void set_state(JobData& job, JobState state, const std::string& error);  // mu_ held
    // The wall clock, in Unix milliseconds, as the injected clock advances (a test's clock
    // moves it too): the time of the manager's start plus the clock's time since.
    int64_t now_unix_ms() const;

    // --- the worker protocol and the failure policy (job_manager_workers.cpp) ---
    // A worker could not render a lease: its range is queued again, and the job FAILS by the
    // poison rule (server/failure_policy.h); a refusal for memory is recorded instead.
    void lease_failed(const std::string& worker_id, const v1::LeaseFailure& failure);  // mu_ held
    // A lease of the job expired: its worker died or stopped heartbeating while rendering it.
    void lease_lost(const LeaseGrant& grant);  // mu_ held
    // Marks these leases of the worker as having rendered iterations (mu_ held).
    void note_lease_progress(const std::string& worker_id,
                             const google::protobuf::RepeatedPtrField<std::string>& lease_ids);
    // FAILS `job` if the poison rule says so (mu_ held).
    void fail_if_poison(JobData& job, const std::string& job_id);
    // A worker refused a lease for memory: recorded, not counted as a failure (mu_ held).
    void lease_refused_for_memory(const std::string& worker_id, JobData& job,
                                  const v1::LeaseFailure& failure);
    // The worker cannot take the job for memory (mu_ held).
    bool lacks_memory_for(const JobData& job, const std::string& worker_id) const;
    // The job was refused for memory and no live worker (seen within the lease timeout) can
    // take it; false without live workers (mu_ held).
    bool memory_blocked(const JobData& job) const;
    // FAILS the jobs that stayed memory-blocked for memory_wait_seconds (mu_ held).
    void fail_memory_blocked();

    // --- frames (job_manager_frames.cpp) ---
    // Starts the adaptive rounds that are due, expires leases and finishes complete frames
    // (tick() without the checkpoints).
    void advance();
    // Writes the checkpoints that are due (all dirty ones with `all`).
    void flush_checkpoints(bool all);
    void finish_frame(const std::string& job_id, uint32_t frame);

    // --- adaptive sampling (job_manager_rounds.cpp; docs/reference/adaptive-sampling.md) ---
    // For each adaptive frame whose round is wholly merged: the next round's mask from the
    // merged exact sums, then its iterations are leased; or, when no pixel is left active,
    // the frame is closed (it completes, as `render` stops). Outside mu_.
    void advance_rounds();
    // The mask fields of a lease of an adaptive job's frame (mu_ held; FrameData::lease_*):
    // false when the frame is not at the lease's round (a bug: the lease is not granted).
    bool fill_lease_mask(const JobData& job, const LeaseGrant& grant, v1::Lease* lease);

    // --- housekeeping (job_manager_housekeeping.cpp) ---
    // Deletes the jobs past the retention time (retain_finished_seconds).
    void apply_retention();
    // Removes the assets no job references and no submit in progress names, untouched for
    // unreferenced_asset_seconds (tick()'s thread only: it paces itself).
    void collect_unreferenced_assets();
    // The assets a job other than `except_job` names, or a submit in progress has pinned
    // (caller holds mu_): what neither a deletion nor the asset sweep may remove.
    std::set<std::string> assets_in_use(const std::string& except_job = {}) const;

    // --- several servers on one store (job_manager_holds.cpp) ---
    // Whether this server may lease, merge and write the job (always on an unshared store;
    // mu_ held).
    bool holds(const JobData& job) const { return !shared_ || job.held; }
    // Renews the holds, records this server's workers and reads the farm's, takes over the
    // jobs nobody holds (when this server has live workers, while no other server with workers
    // holds fewer jobs: all that rule allows in one call), and refreshes the jobs other
    // servers hold from the store. tick()'s thread, every hold_seconds / 4.
    void sync_shared(bool force);
    // This server's live workers recorded in the store, every server's read back into
    // farm_workers_ (outside mu_).
    void sync_farm_workers();
    // What the store records of a job's frames (the ranges of their last checkpoints).
    std::vector<FramePlan> stored_plans(const JobRow& row);
    // A job this server does not hold, as the store records it: added, or its state and
    // progress brought up to date (outside mu_).
    void refresh_job(const JobRow& row);
    // A job submitted through another server since the last sync: read from the store now
    // (a client may ask this server about it at once). True when it is known now.
    bool learn_job(const std::string& job_id);
    // Takes the job's sums over from the last checkpoints (the hold of `epoch` is taken).
    void take_over(const std::string& job_id, int64_t epoch, const std::string& previous);
    // Another server took the job: its leases are void and its sums dropped (mu_ held).
    void give_up(JobData& job, const char* why);
    // Renews the hold before a checkpoint or result of the job is written: false (and the
    // write skipped) when another server took it (outside mu_).
    bool still_held(const std::string& job_id);
    // A stopping server gives its holds up, so that others take its jobs at once.
    void release_holds();

    // --- views (job_manager_views.cpp) ---
    void fill_job(const JobData& job, v1::Job* out) const;  // mu_ held
    // The state clients see: WAITING (never stored) for an unfinished job that is
    // memory-blocked and that no worker holds a lease of, else the scheduler's (mu_ held).
    v1::JobState shown_state(const JobData& job) const;

    ServerOptions options_;
    Scheduler::ClockFn clock_;
    TimePoint start_clock_;
    int64_t start_unix_ms_ = 0;
    std::optional<TimePoint> last_asset_sweep_;  // tick()'s thread only
    ServerMetrics metrics_;
    // The job store (server/job_store.h) the options name; store_ refers to it.
    std::unique_ptr<JobStore> owned_store_;
    JobStore& store_;
    FrameFiles frame_files_;
    AssetStore assets_;
    StreamGuards client_streams_;
    StreamGuards worker_streams_;
    StreamGuards long_streams_;
    mutable std::mutex mu_;
    Scheduler scheduler_;
    std::map<std::string, std::shared_ptr<JobData>> jobs_;
    WorkerRegistry workers_;
    // The assets named by submits in progress, with how many (under mu_): neither the asset
    // sweep nor a job's deletion removes them.
    std::map<std::string, int> submitting_assets_;
    int64_t next_sequence_ = 1;
    std::mutex finish_mu_;  // one frame finishes at a time
    // A shared store (JobStore::shared): several servers, holds (docs/design/job-store.md).
    bool shared_ = false;
    std::string server_id_;
    std::optional<TimePoint> last_sync_;  // tick()'s thread only
    // The rows of reported leases, deleted in one batch by tick() (delete_reported_leases):
    // a Report merges with its job's report slot held, and a round trip to the database
    // there made every other report of the job wait for it (docs/design/job-store.md,
    // "Connections"). A row left a while longer changes nothing: its range is merged, never
    // leased again by this holder, and a new holder voids every row of the job first.
    std::mutex reported_mu_;
    std::vector<std::string> reported_leases_;
    // Every server's workers as the store recorded them at the last sync (under mu_): the
    // dashboard of any server lists the whole farm (docs/design/job-store.md).
    std::vector<FarmWorkerRow> farm_workers_;
};

}  // namespace render::server
