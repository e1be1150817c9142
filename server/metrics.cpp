#include "server/metrics.h"

#include <prometheus/text_serializer.h>

#include <set>
#include <sstream>

namespace render::server {

using prometheus::BuildCounter;
using prometheus::BuildGauge;
using prometheus::BuildHistogram;

namespace {

const char* state_label(size_t state) {
    switch (JobState(state)) {
        case JobState::Queued:
            return "queued";
        case JobState::Running:
            return "running";
        case JobState::Done:
            return "done";
        case JobState::Cancelled:
            return "cancelled";
        case JobState::Failed:
            return "failed";
    }
    if (state == 6) return "waiting";  // v1::JOB_STATE_WAITING: shown, never stored
    return "unknown";
}

prometheus::Histogram::BucketBoundaries seconds_buckets() {
    return {0.0001, 0.0003, 0.001, 0.003, 0.01, 0.03, 0.1, 0.3, 1, 3};
}

prometheus::Histogram::BucketBoundaries byte_buckets() {
    return {1 << 10, 1 << 12, 1 << 14, 1 << 16, 1 << 18, 1 << 20, 1 << 22, 1 << 24, 1 << 26};
}

}  // namespace

ServerMetrics::ServerMetrics() : registry_(std::make_shared<prometheus::Registry>()) {
    auto& r = *registry_;
    jobs_ =
        &BuildGauge()
             .Name("render_jobs")
             .Help(
                 "Jobs known to the server, by state (waiting: every live worker refused it for "
                 "memory and none holds a lease of it; not counted as running)")
             .Register(r);
    for (size_t s = 1; s < jobs_by_state_.size(); ++s)
        jobs_by_state_[s] = &jobs_->Add({{"state", state_label(s)}});
    asset_store_bytes_ = &BuildGauge()
                              .Name("render_asset_store_bytes")
                              .Help(
                                  "The stored assets' total size (server --max-store-size); "
                                  "down when DeleteJob removes assets no other job uses")
                              .Register(r)
                              .Add({});
    queued_iterations_ = &BuildGauge()
                              .Name("render_queue_iterations")
                              .Help("Iterations of unfinished jobs not handed out to a worker yet")
                              .Register(r)
                              .Add({});
    workers_connected_ =
        &BuildGauge()
             .Name("render_workers_connected")
             .Help("Workers heard from (lease request, heartbeat) within the lease timeout")
             .Register(r)
             .Add({});
    leases_active_ = &BuildGauge()
                          .Name("render_leases_active")
                          .Help("Leases handed out and not yet reported, expired or given up")
                          .Register(r)
                          .Add({});
    leases_granted_ = &BuildCounter()
                           .Name("render_leases_granted_total")
                           .Help("Leases (ranges of iterations) handed to workers")
                           .Register(r)
                           .Add({});
    leases_expired_ = &BuildCounter()
                           .Name("render_leases_expired_total")
                           .Help("Leases not heartbeaten within the lease timeout")
                           .Register(r)
                           .Add({});
    leases_requeued_ =
        &BuildCounter()
             .Name("render_leases_requeued_total")
             .Help("Leases whose range went back to the queue (expired or given up by a worker)")
             .Register(r)
             .Add({});
    leases_failed_ = &BuildCounter()
                          .Name("render_leases_failed_total")
                          .Help("Leases a worker reported it could not render")
                          .Register(r)
                          .Add({});
    leases_refused_memory_ = &BuildCounter()
                                  .Name("render_leases_refused_memory_total")
                                  .Help(
                                      "Leases a worker refused for memory (its estimate over its "
                                      "limit); not failures: the job waits for a larger worker")
                                  .Register(r)
                                  .Add({});
    leases_refused_store_ = &BuildCounter()
                                 .Name("render_leases_refused_by_store_total")
                                 .Help(
                                     "Ranges a shared store's claim_lease refused (another "
                                     "server's lease or merged range overlapped them)")
                                 .Register(r)
                                 .Add({});
    jobs_taken_ = &BuildCounter()
                       .Name("render_jobs_taken_total")
                       .Help(
                           "Jobs this server took the hold of on a shared store (a job "
                           "nobody held, or one whose holder's hold ran out)")
                       .Register(r)
                       .Add({});
    jobs_expired_ = &BuildCounter()
                         .Name("render_jobs_expired_total")
                         .Help(
                             "Finished, failed or cancelled jobs deleted by the retention rule "
                             "(server --retain-finished), as DeleteJob deletes them")
                         .Register(r)
                         .Add({});
    assets_collected_ = &BuildCounter()
                             .Name("render_assets_collected_total")
                             .Help(
                                 "Uploaded assets that no job referenced, removed after the grace "
                                 "period (server --unreferenced-asset-grace)")
                             .Register(r)
                             .Add({});
    assets_collected_bytes_ = &BuildCounter()
                                   .Name("render_assets_collected_bytes_total")
                                   .Help(
                                       "The bytes of the assets render_assets_collected_total "
                                       "counts")
                                   .Register(r)
                                   .Add({});
    reports_merged_ = &BuildCounter()
                           .Name("render_reports_merged_total")
                           .Help("Worker reports whose sums were merged into a frame")
                           .Register(r)
                           .Add({});
    reports_dropped_ = &BuildCounter()
                            .Name("render_reports_dropped_total")
                            .Help(
                                "Worker reports dropped unmerged, by reason (duplicate: its "
                                "range was already merged)")
                            .Register(r);
    for (const char* reason : {"duplicate", "unknown_lease", "reissued", "job_inactive"})
        reports_dropped_->Add({{"reason", reason}});
    farm_jobs_held_ = &BuildGauge()
                           .Name("render_farm_jobs_held")
                           .Help(
                               "Several servers on one store: the unfinished jobs each server "
                               "holds, by its advertised address (the store at the last sync)")
                           .Register(r);
    farm_jobs_unheld_ = &BuildGauge()
                             .Name("render_farm_jobs_unheld")
                             .Help(
                                 "Several servers on one store: unfinished jobs no live server "
                                 "holds (waiting for a server with workers to take them)")
                             .Register(r)
                             .Add({});
    farm_workers_ = &BuildGauge()
                         .Name("render_farm_workers")
                         .Help(
                             "Several servers on one store: the live workers of each server, by "
                             "its advertised address (the store at the last sync)")
                         .Register(r);
    store_connections_ = &BuildGauge()
                              .Name("render_store_connections")
                              .Help("The PostgreSQL store's connection pool: its size")
                              .Register(r)
                              .Add({});
    store_connections_in_use_ = &BuildGauge()
                                     .Name("render_store_connections_in_use")
                                     .Help("The PostgreSQL store's connections lent now")
                                     .Register(r)
                                     .Add({});
    store_connections_made_ = &BuildCounter()
                                   .Name("render_store_connections_made_total")
                                   .Help(
                                       "PostgreSQL connections made: the pool's first ones and "
                                       "those replacing a broken or failed one")
                                   .Register(r)
                                   .Add({});
    store_connection_waits_ = &BuildCounter()
                                   .Name("render_store_connection_waits_total")
                                   .Help(
                                       "Store operations that found every PostgreSQL connection "
                                       "lent and waited for one (server --store-connections)")
                                   .Register(r)
                                   .Add({});
    store_connection_wait_seconds_ = &BuildCounter()
                                          .Name("render_store_connection_wait_seconds_total")
                                          .Help(
                                              "Time store operations waited for a PostgreSQL "
                                              "connection, summed")
                                          .Register(r)
                                          .Add({});
    reports_forwarded_ = &BuildCounter()
                              .Name("render_reports_forwarded_total")
                              .Help(
                                  "Reports for leases another server granted, forwarded to "
                                  "the job's holder on a shared store, by result (merged, "
                                  "not_merged: the holder dropped it, failed: not reached)")
                              .Register(r);
    for (const char* result : {"merged", "not_merged", "failed"})
        reports_forwarded_->Add({{"result", result}});
    auto& bytes = BuildCounter()
                      .Name("render_received_bytes_total")
                      .Help("Bytes received from workers (reports) and clients (asset uploads)")
                      .Register(r);
    bytes_reports_ = &bytes.Add({{"kind", "report"}});
    bytes_assets_ = &bytes.Add({{"kind", "asset"}});
    merge_seconds_ = &BuildHistogram()
                          .Name("render_merge_seconds")
                          .Help("Time to add a report's sums to its frame's sums")
                          .Register(r)
                          .Add({}, seconds_buckets());
    store_seconds_ =
        &BuildHistogram()
             .Name("render_store_seconds")
             .Help("Time to write a frame's checkpoint and record the merged range in the store")
             .Register(r)
             .Add({}, seconds_buckets());
    report_bytes_ = &BuildHistogram()
                         .Name("render_report_bytes")
                         .Help("Size of a worker report on the wire (header and values)")
                         .Register(r)
                         .Add({}, byte_buckets());
    job_rate_ = &BuildGauge()
                     .Name("render_job_iterations_per_second")
                     .Help("Merged iterations per second of render time, per unfinished job")
                     .Register(r);
    job_error_ = &BuildGauge()
                      .Name("render_job_relative_error")
                      .Help(
                          "Estimated relative error (odd/even) of an unfinished job's worst "
                          "frame; 1 before anything merged")
                      .Register(r);
    job_memory_ = &BuildGauge()
                       .Name("render_job_waiting_for_memory_bytes")
                       .Help(
                           "The memory an unfinished job needs while every live worker refused "
                           "it for memory (server --memory-wait); 0 when a worker can take it")
                       .Register(r);
    worker_iterations_ = &BuildGauge()
                              .Name("render_worker_iterations_per_second")
                              .Help(
                                  "A worker's iterations per second over its current or last "
                                  "lease (heartbeats, reports)")
                              .Register(r);
    worker_samples_ = &BuildGauge()
                           .Name("render_worker_samples_per_second")
                           .Help(
                               "A worker's camera samples per second over its current or last "
                               "lease")
                           .Register(r);
    worker_rays_ = &BuildGauge()
                        .Name("render_worker_rays_per_second")
                        .Help("A worker's rays traced per second over its current or last lease")
                        .Register(r);
    worker_leases_ =
        &BuildGauge().Name("render_worker_leases").Help("Leases a worker holds now").Register(r);
}

void ServerMetrics::report_merged(double merge_seconds, double store_seconds) {
    reports_merged_->Increment();
    merge_seconds_->Observe(merge_seconds);
    store_seconds_->Observe(store_seconds);
}

void ServerMetrics::report_dropped(std::string_view reason) {
    std::string label(reason);
    if (label == "already_merged") label = "duplicate";
    if (label == "expired_and_reissued") label = "reissued";
    std::lock_guard lock(mu_);
    reports_dropped_->Add({{"reason", label}}).Increment();
}

void ServerMetrics::report_forwarded(std::string_view result) {
    std::lock_guard lock(mu_);
    reports_forwarded_->Add({{"result", std::string(result)}}).Increment();
}

void ServerMetrics::report_received(uint64_t bytes) {
    bytes_reports_->Increment(double(bytes));
    report_bytes_->Observe(double(bytes));
}

void ServerMetrics::asset_received(uint64_t bytes) {
    bytes_assets_->Increment(double(bytes));
}

void ServerMetrics::set_counter(prometheus::Counter& counter, uint64_t total) {
    const double now = counter.Value();
    if (double(total) > now) counter.Increment(double(total) - now);
}

std::string ServerMetrics::exposition(const MetricsSnapshot& s) {
    std::lock_guard lock(mu_);
    for (size_t i = 1; i < jobs_by_state_.size(); ++i)
        jobs_by_state_[i]->Set(double(s.jobs_by_state[i]));
    queued_iterations_->Set(double(s.queued_iterations));
    asset_store_bytes_->Set(double(s.asset_store_bytes));
    workers_connected_->Set(double(s.workers.size()));
    leases_active_->Set(double(s.active_leases));
    set_counter(*leases_granted_, s.leases.granted);
    set_counter(*leases_expired_, s.leases.expired);
    set_counter(*leases_requeued_, s.leases.expired + s.leases.released);

    std::set<std::string> jobs_seen, workers_seen;
    for (const JobSnapshot& j : s.jobs) {
        jobs_seen.insert(j.id);
        auto& children = job_children_[j.id];
        if (children.empty())
            children = {&job_rate_->Add({{"job", j.id}}), &job_error_->Add({{"job", j.id}}),
                        &job_memory_->Add({{"job", j.id}})};
        children[0]->Set(j.iterations_per_second);
        children[1]->Set(j.relative_error);
        children[2]->Set(j.memory_wanted_bytes);
    }
    for (auto it = job_children_.begin(); it != job_children_.end();) {
        if (jobs_seen.count(it->first)) {
            ++it;
            continue;
        }
        job_rate_->Remove(it->second[0]);
        job_error_->Remove(it->second[1]);
        job_memory_->Remove(it->second[2]);
        it = job_children_.erase(it);
    }
    for (const WorkerSnapshot& w : s.workers) {
        workers_seen.insert(w.id);
        auto& children = worker_children_[w.id];
        if (children.empty()) {
            const prometheus::Labels labels{{"worker", w.id}, {"host", w.host}};
            children = {&worker_iterations_->Add(labels), &worker_samples_->Add(labels),
                        &worker_rays_->Add(labels), &worker_leases_->Add(labels)};
        }
        children[0]->Set(w.iterations_per_second);
        children[1]->Set(w.samples_per_second);
        children[2]->Set(w.rays_per_second);
        children[3]->Set(double(w.active_leases));
    }
    for (auto it = worker_children_.begin(); it != worker_children_.end();) {
        if (workers_seen.count(it->first)) {
            ++it;
            continue;
        }
        worker_iterations_->Remove(it->second[0]);
        worker_samples_->Remove(it->second[1]);
        worker_rays_->Remove(it->second[2]);
        worker_leases_->Remove(it->second[3]);
        it = worker_children_.erase(it);
    }
    farm_jobs_unheld_->Set(double(s.farm_jobs_unheld));
    for (const auto& [server, count] : s.farm_jobs_held) {
        auto& child = farm_held_children_[server];
        if (!child) child = &farm_jobs_held_->Add({{"server", server}});
        child->Set(double(count));
    }
    for (auto it = farm_held_children_.begin(); it != farm_held_children_.end();) {
        if (s.farm_jobs_held.count(it->first)) {
            ++it;
            continue;
        }
        farm_jobs_held_->Remove(it->second);
        it = farm_held_children_.erase(it);
    }
    for (const auto& [server, count] : s.farm_workers) {
        auto& child = farm_workers_children_[server];
        if (!child) child = &farm_workers_->Add({{"server", server}});
        child->Set(double(count));
    }
    for (auto it = farm_workers_children_.begin(); it != farm_workers_children_.end();) {
        if (s.farm_workers.count(it->first)) {
            ++it;
            continue;
        }
        farm_workers_->Remove(it->second);
        it = farm_workers_children_.erase(it);
    }
    if (s.store_connections) {
        const StoreConnectionStats& c = *s.store_connections;
        store_connections_->Set(double(c.size));
        store_connections_in_use_->Set(double(c.in_use));
        // The pool counts from its start: the counters follow it.
        auto follow = [](prometheus::Counter* counter, double total) {
            if (total > counter->Value()) counter->Increment(total - counter->Value());
        };
        follow(store_connections_made_, double(c.connections_made));
        follow(store_connection_waits_, double(c.waited));
        follow(store_connection_wait_seconds_, c.wait_seconds);
    }
    std::ostringstream out;
    prometheus::TextSerializer().Serialize(out, registry_->Collect());
    return out.str();
}

}  // namespace render::server
