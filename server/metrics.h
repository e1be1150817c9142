#pragma once

// The server's Prometheus metrics (prometheus-cpp's core library: registry, families and the
// text serializer; the HTTP side is server/http_server.h). Counters and histograms are updated
// where things happen; gauges (jobs by state, queue, workers, rates) are set from a snapshot of
// the JobManager at each scrape. Names and meanings: docs/guide/service.md, "Metrics".

#include <prometheus/counter.h>
#include <prometheus/family.h>
#include <prometheus/gauge.h>
#include <prometheus/histogram.h>
#include <prometheus/registry.h>

#include <array>
#include <cstdint>
#include <map>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "server/job_store.h"
#include "server/scheduler.h"

namespace render::server {

struct WorkerSnapshot {
    std::string id, host;
    uint32_t threads = 0;
    double iterations_per_second = 0, samples_per_second = 0, rays_per_second = 0;
    uint32_t active_leases = 0;
};

struct JobSnapshot {
    std::string id;
    double iterations_per_second = 0;  // summed over the job's unfinished frames
    double relative_error = 1;         // the largest of its frames'
    // The memory it needs while no live worker can take it (refused for memory), else 0.
    double memory_wanted_bytes = 0;
};

struct MetricsSnapshot {
    // Indexed by the state clients see (v1::JobState 1..6: JobState's, and 6 for WAITING).
    std::array<uint64_t, 7> jobs_by_state{};
    uint64_t queued_iterations = 0;
    uint64_t asset_store_bytes = 0;  // what --max-store-size counts
    uint64_t active_leases = 0;
    LeaseCounters leases;
    std::vector<WorkerSnapshot> workers;  // connected ones
    std::vector<JobSnapshot> jobs;        // unfinished ones
    // Several servers on one store (docs/design/job-store.md): the unfinished jobs each live
    // server holds, by its advertised address, and those nobody holds, as the last sync read
    // them from the store (empty and 0 on a store of one server).
    std::map<std::string, uint64_t> farm_jobs_held;
    uint64_t farm_jobs_unheld = 0;
    // The live workers of each server, by its advertised address (the farm's workers as the
    // store had them at the last sync; empty on a store of one server).
    std::map<std::string, uint64_t> farm_workers;
    // The store's connection pool (PostgreSQL; docs/design/job-store.md, "Connections").
    std::optional<StoreConnectionStats> store_connections;
};

class ServerMetrics {
  public:
    ServerMetrics();

    // A worker reported a lease it could not render.
    void lease_failed() { leases_failed_->Increment(); }
    // A worker refused a lease for memory (not a failure: the job waits for a larger one).
    void lease_refused_memory() { leases_refused_memory_->Increment(); }
    // A shared store's claim_lease refused a range this server's scheduler chose.
    void lease_refused_by_store() { leases_refused_store_->Increment(); }
    // This server took a job over on a shared store (its first hold, or a lapsed one's).
    void job_taken() { jobs_taken_->Increment(); }
    // A report's sums were added (merge) and checkpointed and stored (store).
    void report_merged(double merge_seconds, double store_seconds);
    // A report was dropped; reason as MergeDecision's to_string or "unknown_lease".
    void report_dropped(std::string_view reason);
    // A report for a lease this server did not grant, forwarded to the job's holder on a
    // shared store: result "merged" (the holder merged it), "not_merged" (the holder dropped
    // it) or "failed" (the holder could not be reached).
    void report_forwarded(std::string_view result);
    // A report's bytes on the wire (header and values), merged or not.
    void report_received(uint64_t bytes);
    // An uploaded asset's bytes.
    void asset_received(uint64_t bytes);
    // A finished, failed or cancelled job deleted by the retention rule (--retain-finished).
    void job_expired() { jobs_expired_->Increment(); }
    // An uploaded asset no job referenced, removed after the grace period.
    void asset_collected(uint64_t bytes) {
        assets_collected_->Increment();
        assets_collected_bytes_->Increment(double(bytes));
    }

    // Sets the gauges from `snapshot` and returns the whole exposition (text format 0.0.4).
    std::string exposition(const MetricsSnapshot& snapshot);

  private:
    void set_counter(prometheus::Counter& counter, uint64_t total);

    std::mutex mu_;  // exposition() and the per-worker/per-job children
    std::shared_ptr<prometheus::Registry> registry_;
    prometheus::Family<prometheus::Gauge>* jobs_;
    std::array<prometheus::Gauge*, 7> jobs_by_state_{};
    prometheus::Gauge* queued_iterations_;
    prometheus::Gauge* asset_store_bytes_;
    prometheus::Gauge* workers_connected_;
    prometheus::Gauge* leases_active_;
    prometheus::Counter* leases_granted_;
    prometheus::Counter* leases_expired_;
    prometheus::Counter* leases_requeued_;
    prometheus::Counter* leases_failed_;
    prometheus::Counter* leases_refused_memory_;
    prometheus::Counter* leases_refused_store_;
    prometheus::Counter* jobs_taken_;
    prometheus::Counter* jobs_expired_;
    prometheus::Counter* assets_collected_;
    prometheus::Counter* assets_collected_bytes_;
    prometheus::Counter* reports_merged_;
    prometheus::Family<prometheus::Counter>* reports_dropped_;
    prometheus::Family<prometheus::Counter>* reports_forwarded_;
    prometheus::Counter* bytes_reports_;
    prometheus::Counter* bytes_assets_;
    prometheus::Histogram* merge_seconds_;
    prometheus::Histogram* store_seconds_;
    prometheus::Histogram* report_bytes_;
    prometheus::Family<prometheus::Gauge>* job_rate_;
    prometheus::Family<prometheus::Gauge>* job_error_;
    prometheus::Family<prometheus::Gauge>* job_memory_;
    prometheus::Family<prometheus::Gauge>* worker_iterations_;
    prometheus::Family<prometheus::Gauge>* worker_samples_;
    prometheus::Family<prometheus::Gauge>* worker_rays_;
    prometheus::Family<prometheus::Gauge>* worker_leases_;
    // Children of the per-job and per-worker families, by job or worker id, so that those of
    // finished jobs and departed workers are removed.
    std::map<std::string, std::vector<prometheus::Gauge*>> job_children_, worker_children_;
    prometheus::Family<prometheus::Gauge>* farm_jobs_held_;
    prometheus::Gauge* farm_jobs_unheld_;
    std::map<std::string, prometheus::Gauge*> farm_held_children_;
    prometheus::Family<prometheus::Gauge>* farm_workers_;
    std::map<std::string, prometheus::Gauge*> farm_workers_children_;
    prometheus::Gauge* store_connections_;
    prometheus::Gauge* store_connections_in_use_;
    prometheus::Counter* store_connections_made_;
    prometheus::Counter* store_connection_waits_;
    prometheus::Counter* store_connection_wait_seconds_;
};

}  // namespace render::server
