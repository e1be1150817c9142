// What clients, the dashboard and the metrics see of the job manager's state: jobs with their
// progress and ETA, the cluster's workers, the Prometheus snapshot (server/metrics.h).

#include "server/job_manager.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <sstream>

#include "server/job_manager_detail.h"

namespace render::server {

using grpc::Status;
using namespace detail;

void JobManager::fill_job(const JobData& job, v1::Job* out) const {
    out->Clear();
    out->set_id(job.row.id);
    out->set_name(job.row.name);
    out->set_state(shown_state(job));
    out->set_priority(job.row.priority);
    *out->mutable_settings() = job.request.settings();
    out->set_error(job.row.error);
    out->set_submitted_unix_ms(job.row.submitted_unix_ms);
    if (!is_terminal(scheduler_.state(job.row.id)) && memory_blocked(job))
        out->set_waiting(job.failures.memory_waiting(options_.memory_wait_seconds));
    const v1::RenderSettings& s = job.request.settings();
    for (uint32_t i = 0; i < job.frames.size(); ++i) {
        FrameProgress p = scheduler_.progress(job.row.id, i);
        v1::FrameStatus* f = out->add_frames();
        f->set_index(i);
        f->set_iterations_done(p.merged);
        f->set_iterations_target(p.target);
        f->set_relative_error(job.frames[i]->relative_error.load());
        double rate = p.elapsed_seconds > 0 ? double(p.merged) / p.elapsed_seconds : 0;
        f->set_iterations_per_second(rate);
        double eta = 0;
        if (!p.done) {
            if (p.target > 0 && rate > 0)
                eta = double(p.target - std::min(p.target, p.merged)) / rate;
            if (s.time_budget_seconds() > 0) {
                double left = std::max(0.0, s.time_budget_seconds() - p.elapsed_seconds);
                eta = p.target > 0 && rate > 0 ? std::min(eta, left) : left;
            }
        }
        f->set_eta_seconds(eta);
        f->set_done(p.done);
        f->set_render_seconds(p.elapsed_seconds);
    }
}

v1::JobState JobManager::shown_state(const JobData& job) const {
    const JobState state = scheduler_.state(job.row.id);
    // A job that was ever leased stays Running in the scheduler (and the store): shown as
    // RUNNING while nobody renders it, it would look stuck.
    if (!is_terminal(state) && memory_blocked(job) && !scheduler_.job_has_lease(job.row.id))
        return v1::JOB_STATE_WAITING;
    return v1::JobState(state);
}

void JobManager::cluster_status(v1::ClusterStatusReply* reply) {
    std::lock_guard lock(mu_);
    for (const auto& [id, w] : workers_.all()) {
        v1::WorkerStatus* s = reply->add_workers();
        s->set_worker_id(id);
        s->set_host(w.host);
        s->set_threads(w.threads);
        s->set_last_seen_unix_ms(w.last_seen_unix_ms);
        auto leases = scheduler_.worker_leases(id);
        if (!leases.empty()) s->set_lease_id(leases.front());
        s->set_active_leases(uint32_t(leases.size()));
        *s->mutable_rates() = w.rates;
    }
    for (const auto& [id, job] : jobs_) {
        const v1::JobState st = shown_state(*job);
        if (st == v1::JOB_STATE_QUEUED) reply->set_queued_jobs(reply->queued_jobs() + 1);
        if (st == v1::JOB_STATE_RUNNING) reply->set_running_jobs(reply->running_jobs() + 1);
        if (st == v1::JOB_STATE_WAITING) reply->set_waiting_jobs(reply->waiting_jobs() + 1);
    }
}

namespace {

// A number JSON can carry (NaN and Inf cannot).
double finite_or_zero(double v) {
    return std::isfinite(v) ? v : 0;
}

}  // namespace

std::string JobManager::farm_json() {
    std::map<std::string, uint64_t> held;
    uint64_t unheld = 0;
    std::vector<FarmWorkerRow> workers;
    {
        std::lock_guard lock(mu_);
        workers = farm_workers_;
        if (shared_) held[options_.advertise_address];  // this server, even holding nothing
        for (const auto& [id, job] : jobs_) {
            if (!shared_ || is_terminal(scheduler_.state(id))) continue;
            if (job->held)
                ++held[options_.advertise_address];
            else if (job->row.owner.live)
                ++held[job->row.owner.address];
            else
                ++unheld;
        }
    }
    // Addresses are HOST:PORT as given to --advertise; quotes and backslashes escaped.
    auto quoted = [](const std::string& s) {
        std::string out = "\"";
        for (char c : s) {
            if (c == '"' || c == '\\') out += '\\';
            if (static_cast<unsigned char>(c) >= 0x20) out += c;
        }
        return out + "\"";
    };
    std::ostringstream out;
    out << "{\"shared\":" << (shared_ ? "true" : "false")
        << ",\"self\":" << quoted(options_.advertise_address) << ",\"servers\":[";
    bool first = true;
    for (const auto& [address, count] : held) {
        out << (first ? "" : ",") << "{\"address\":" << quoted(address)
            << ",\"jobs_held\":" << count
            << ",\"self\":" << (address == options_.advertise_address ? "true" : "false") << "}";
        first = false;
    }
    // Every server's workers as the store has them from the last sync (this server's too).
    out << "],\"jobs_unheld\":" << unheld << ",\"workers\":[";
    first = true;
    for (const FarmWorkerRow& w : workers) {
        out << (first ? "" : ",") << "{\"worker_id\":" << quoted(w.worker_id)
            << ",\"server\":" << quoted(w.server_address)
            << ",\"self\":" << (w.server == server_id_ ? "true" : "false")
            << ",\"host\":" << quoted(w.host) << ",\"threads\":" << w.threads
            << ",\"last_seen_unix_ms\":" << w.seen_unix_ms
            << ",\"iterations_per_second\":" << finite_or_zero(w.iterations_per_second)
            << ",\"samples_per_second\":" << finite_or_zero(w.samples_per_second)
            << ",\"rays_per_second\":" << finite_or_zero(w.rays_per_second) << "}";
        first = false;
    }
    out << "]}";
    return out.str();
}

std::string JobManager::metrics_text() {
    MetricsSnapshot s;
    {
        std::lock_guard lock(mu_);
        const auto connected_ms = int64_t(options_.lease_timeout_seconds * 1000);
        workers_.for_each_live(unix_ms(), connected_ms,
                               [&](const std::string& id, const WorkerInfo& w) {
                                   WorkerSnapshot ws;
                                   ws.id = id;
                                   ws.host = w.host;
                                   ws.threads = w.threads;
                                   ws.iterations_per_second = w.rates.iterations_per_second();
                                   ws.samples_per_second = w.rates.samples_per_second();
                                   ws.rays_per_second = w.rates.rays_per_second();
                                   ws.active_leases = uint32_t(scheduler_.worker_leases(id).size());
                                   s.workers.push_back(std::move(ws));
                               });
        if (shared_)
            for (const FarmWorkerRow& w : farm_workers_) ++s.farm_workers[w.server_address];
        for (const auto& [id, job] : jobs_) {
            const JobState state = scheduler_.state(id);
            const size_t shown = size_t(shown_state(*job));
            if (shown < s.jobs_by_state.size()) ++s.jobs_by_state[shown];
            if (is_terminal(state)) continue;
            if (shared_) {
                if (job->held)
                    ++s.farm_jobs_held[options_.advertise_address];
                else if (job->row.owner.live)
                    ++s.farm_jobs_held[job->row.owner.address];
                else
                    ++s.farm_jobs_unheld;
            }
            JobSnapshot js;
            js.id = id;
            js.relative_error = 0;
            if (memory_blocked(*job))
                js.memory_wanted_bytes = double(job->failures.memory_needed());
            for (uint32_t i = 0; i < job->frames.size(); ++i) {
                const FrameProgress p = scheduler_.progress(id, i);
                if (!p.done && p.elapsed_seconds > 0)
                    js.iterations_per_second += double(p.merged) / p.elapsed_seconds;
                js.relative_error =
                    std::max(js.relative_error, job->frames[i]->relative_error.load());
            }
            s.jobs.push_back(std::move(js));
        }
        s.queued_iterations = scheduler_.queued_iterations();
        s.asset_store_bytes = assets_.stored_bytes();
        s.active_leases = scheduler_.active_lease_count();
        s.leases = scheduler_.lease_counters();
    }
    s.store_connections = store_.connection_stats();  // the pool's own lock, not mu_
    return metrics_.exposition(s);
}

}  // namespace render::server
