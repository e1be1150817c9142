// Several servers on one shared store (docs/design/job-store.md, "Several servers, one farm"):
// each unfinished job's sums are held by one server at a time, through a hold in the store
// with an expiry and an epoch. The holder alone leases the job's ranges (through claim_lease),
// merges its reports, writes its checkpoints and its finished frames. A server whose hold
// lapsed and was taken drops the job's sums and leases; the new holder starts from the last
// checkpoint, so a range merged after it is leased again and never counted twice.

#include <algorithm>
#include <chrono>
#include <map>
#include <set>

#include "core/util/log.h"
#include "server/job_manager.h"
#include "server/job_manager_detail.h"
#include "server/validation.h"

namespace render::server {

using namespace detail;

namespace {

int64_t hold_ms(const ServerOptions& options) {
    return std::max<int64_t>(200, int64_t(options.hold_seconds * 1000));
}

// A server records its workers every sync (a quarter of its hold): rows older than half a
// hold are a dead server's, neither shown nor counted when the jobs are spread (so a dead
// server's workers never hold a take-over back past its hold); after a minute (or ten holds)
// they are removed.
int64_t live_workers_ms(const ServerOptions& options) {
    return hold_ms(options) / 2;
}

int64_t forget_workers_ms(const ServerOptions& options) {
    return std::max<int64_t>(60000, 10 * hold_ms(options));
}

}  // namespace

std::vector<std::string> JobManager::held_jobs() {
    std::lock_guard lock(mu_);
    std::vector<std::string> out;
    for (const auto& [id, job] : jobs_)
        if (holds(*job) && !is_terminal(scheduler_.state(id))) out.push_back(id);
    return out;
}

std::vector<FramePlan> JobManager::stored_plans(const JobRow& row) {
    v1::SubmitJobRequest request;
    request.ParseFromString(row.request);
    std::vector<FramePlan> plans;
    for (const FrameRow& fr : store_.load_frames(row.id)) {
        FramePlan plan;
        plan.target = request.settings().iterations();
        plan.budget_seconds = request.settings().time_budget_seconds();
        plan.elapsed_seconds = fr.elapsed_seconds;
        plan.done = fr.done;
        for (const Range& r : store_.merged_ranges(row.id, fr.index)) plan.merged.add(r);
        plans.push_back(std::move(plan));
    }
    return plans;
}

void JobManager::refresh_job(const JobRow& row) {
    std::vector<FramePlan> plans;
    try {
        plans = stored_plans(row);
    } catch (const std::exception& e) {
        Log("error", "store_failed").kv("job", row.id).kv("error", e.what());
        return;
    }
    std::lock_guard lock(mu_);
    auto job = find(row.id);
    if (!job) {
        job = std::make_shared<JobData>();
        if (!job->request.ParseFromString(row.request)) {
            Log("error", "restore_failed").kv("job", row.id).kv("error", "unreadable request");
            return;
        }
        job->settings = job_settings(job->request);
        for (size_t i = 0; i < plans.size(); ++i)
            job->frames.push_back(std::make_unique<FrameData>());
        job->row = row;
        jobs_[row.id] = job;
        Log("info", "job_seen").kv("job", row.id).kv("holder", row.owner.address);
    }
    if (job->held) return;  // taken by this server meanwhile
    if (plans.size() != job->frames.size()) return;
    job->row = row;
    job->request.set_priority(row.priority);
    scheduler_.add_job(row.id, row.priority, uint64_t(row.sequence), JobState(row.state),
                       std::move(plans));
}

bool JobManager::learn_job(const std::string& job_id) {
    if (!shared_ || !is_safe_id(job_id)) return false;
    try {
        for (const JobRow& row : store_.load_jobs())
            if (row.id == job_id) {
                refresh_job(row);
                std::lock_guard lock(mu_);
                return find(job_id) != nullptr;
            }
    } catch (const std::exception& e) {
        Log("error", "store_failed").kv("job", job_id).kv("error", e.what());
    }
    return false;
}

void JobManager::sync_shared(bool force) {
    const TimePoint now = clock_();
    const double every = std::max(0.05, options_.hold_seconds / 4);
    if (!force && last_sync_ && std::chrono::duration<double>(now - *last_sync_).count() < every)
        return;
    last_sync_ = now;

    // 1. Renew the holds first: a hold that lapses is taken by another server.
    std::vector<std::pair<std::string, int64_t>> held;
    {
        std::lock_guard lock(mu_);
        for (const auto& [id, job] : jobs_)
            if (job->held) held.emplace_back(id, job->hold_epoch);
    }
    for (const auto& [id, epoch] : held) {
        bool kept = true;
        try {
            kept = store_.renew_job(id, server_id_, epoch, hold_ms(options_));
        } catch (const std::exception& e) {
            // The database away: nobody can take the job meanwhile (taking needs it too).
            Log("error", "hold_renewal_failed").kv("job", id).kv("error", e.what());
        }
        if (!kept) {
            std::lock_guard lock(mu_);
            if (auto job = find(id); job && job->held && job->hold_epoch == epoch)
                give_up(*job, "taken by another server");
        }
    }

    sync_farm_workers();

    std::vector<JobRow> rows;
    try {
        rows = store_.load_jobs();
    } catch (const std::exception& e) {
        Log("error", "store_failed").kv("what", "load_jobs").kv("error", e.what());
        return;
    }

    // 2. The jobs other servers hold (or nobody does), as the store records them.
    struct Seen {
        bool held;
        int state;
    };
    std::map<std::string, Seen> seen;
    {
        std::lock_guard lock(mu_);
        for (const auto& [id, job] : jobs_) seen[id] = {job->held, int(scheduler_.state(id))};
    }
    std::set<std::string> present;
    for (const JobRow& row : rows) {
        present.insert(row.id);
        auto it = seen.find(row.id);
        if (it != seen.end() && it->second.held) {
            // Held here: a cancellation or a priority set through another server applies.
            std::lock_guard lock(mu_);
            auto job = find(row.id);
            if (!job || !job->held) continue;
            if (row.state == int(JobState::Cancelled) && !is_terminal(scheduler_.state(row.id))) {
                set_state(*job, JobState::Cancelled, "");
                Log("info", "job_cancelled").kv("job", row.id).kv("through", "another server");
            }
            if (row.priority != job->row.priority && !is_terminal(scheduler_.state(row.id))) {
                scheduler_.set_priority(row.id, row.priority);
                job->row.priority = row.priority;
                job->request.set_priority(row.priority);
            }
            continue;
        }
        // A finished job is read once more when its state changes, then left alone.
        if (it != seen.end() && is_terminal(JobState(it->second.state)) &&
            it->second.state == row.state)
            continue;
        refresh_job(row);
    }
    {
        // Deleted through another server.
        std::lock_guard lock(mu_);
        for (auto it = jobs_.begin(); it != jobs_.end();) {
            if (present.count(it->first) || it->second->held) {
                ++it;
                continue;
            }
            scheduler_.set_state(it->first, JobState::Cancelled);
            scheduler_.remove_job(it->first);
            Log("info", "job_gone").kv("job", it->first);
            it = jobs_.erase(it);
        }
    }

    // 3. Take over the jobs nobody holds, the highest priority first, while this server has
    // workers to render them and no other server with workers holds fewer: the jobs spread
    // over the servers that have workers, a server holding none included
    // (docs/design/job-store.md, "Spreading the jobs": a server's workers lease only the jobs
    // it holds). A dead server's jobs are taken together once their holds run out, not one
    // per sync.
    std::map<std::string, int> holding;
    {
        std::lock_guard lock(mu_);
        if (workers_.live(unix_ms(), int64_t(options_.lease_timeout_seconds * 1000)).empty())
            return;
        for (const FarmWorkerRow& w : farm_workers_) holding[w.server];  // has workers: 0 held
    }
    std::vector<const JobRow*> unheld;
    for (const JobRow& row : rows) {
        if (is_terminal(JobState(row.state))) continue;
        if (row.owner.live)
            ++holding[row.owner.server];
        else
            unheld.push_back(&row);
    }
    std::stable_sort(unheld.begin(), unheld.end(),
                     [](const JobRow* a, const JobRow* b) { return a->priority > b->priority; });
    // At most one job never held (or released) per sync: servers starting together record
    // their workers at their own first syncs, and one that took every new job at once would
    // leave the others' workers idle (jobs held are not handed over). A dead server's jobs
    // (a hold that ran out) are taken together.
    bool took_new = false;
    for (const JobRow* candidate : unheld) {
        const bool is_new = candidate->owner.server.empty();
        if (is_new && took_new) continue;
        const int mine = holding[server_id_];
        for (const auto& [server, count] : holding)
            if (server != server_id_ && count < mine) return;
        std::optional<int64_t> epoch;
        try {
            epoch = store_.take_job(candidate->id, server_id_, options_.advertise_address,
                                    hold_ms(options_));
        } catch (const std::exception& e) {
            Log("error", "store_failed").kv("job", candidate->id).kv("error", e.what());
            return;
        }
        if (!epoch) continue;  // another server took it first
        took_new = took_new || is_new;
        ++holding[server_id_];
        take_over(candidate->id, *epoch, candidate->owner.server);
    }
}

void JobManager::sync_farm_workers() {
    std::vector<FarmWorkerRow> mine;
    {
        std::lock_guard lock(mu_);
        const auto live_ms = int64_t(options_.lease_timeout_seconds * 1000);
        workers_.for_each_live(unix_ms(), live_ms, [&](const std::string& id, const WorkerInfo& w) {
            FarmWorkerRow row;
            row.worker_id = id;
            row.server_address = options_.advertise_address;
            row.host = w.host;
            row.threads = w.threads;
            row.version = w.version;
            row.seen_unix_ms = w.last_seen_unix_ms;
            row.iterations_per_second = w.rates.iterations_per_second();
            row.samples_per_second = w.rates.samples_per_second();
            row.rays_per_second = w.rates.rays_per_second();
            mine.push_back(std::move(row));
        });
    }
    try {
        store_.record_workers(server_id_, mine, forget_workers_ms(options_));
        std::vector<FarmWorkerRow> farm = store_.load_workers(live_workers_ms(options_));
        std::lock_guard lock(mu_);
        farm_workers_ = std::move(farm);
    } catch (const std::exception& e) {
        Log("error", "store_failed").kv("what", "farm_workers").kv("error", e.what());
    }
}

void JobManager::take_over(const std::string& job_id, int64_t epoch, const std::string& previous) {
    std::shared_ptr<JobData> job;
    {
        std::lock_guard lock(mu_);
        job = find(job_id);
    }
    JobRow row;
    std::vector<FramePlan> plans;
    std::vector<std::unique_ptr<FrameData>> loaded;
    int voided = 0;
    try {
        // The predecessor's leases are void: their reports reach it (dead, or dropping them
        // as no longer its job) or this server (which does not know them): never merged.
        voided = store_.clear_job_leases(job_id);
        std::vector<JobRow> rows = store_.load_jobs();
        auto it =
            std::find_if(rows.begin(), rows.end(), [&](const JobRow& r) { return r.id == job_id; });
        if (!job || it == rows.end()) throw std::runtime_error("the job is gone");
        row = *it;
        for (const FrameRow& fr : store_.load_frames(job_id)) {
            FramePlan plan;
            plan.target = job->request.settings().iterations();
            plan.budget_seconds = job->request.settings().time_budget_seconds();
            plan.elapsed_seconds = fr.elapsed_seconds;
            plan.done = fr.done;
            auto data = std::make_unique<FrameData>();
            data->hold_epoch = epoch;  // loads the newest checkpoint of an earlier hold
            if (fr.done) {
                for (const Range& r : store_.merged_ranges(job_id, fr.index)) plan.merged.add(r);
            } else {
                // What the last checkpoint holds is merged; what merged after it (on the
                // predecessor) is leased again.
                frame_files_.load_checkpoint(job_id, fr.index, row.width, row.height, job->settings,
                                             *data, plan);
                store_.set_merged_ranges(job_id, fr.index, plan.merged.ranges());
            }
            plans.push_back(std::move(plan));
            loaded.push_back(std::move(data));
        }
    } catch (const std::exception& e) {
        Log("error", "take_over_failed").kv("job", job_id).kv("error", e.what());
        try {
            store_.release_job(job_id, server_id_, epoch);
        } catch (const std::exception&) {
        }
        return;
    }
    std::lock_guard lock(mu_);
    if (loaded.size() != job->frames.size() || find(job_id) != job) {
        Log("error", "take_over_failed").kv("job", job_id).kv("error", "frames differ");
        return;
    }
    for (size_t i = 0; i < loaded.size(); ++i) {
        FrameData& frame = *job->frames[i];
        std::lock_guard frame_lock(frame.mu);
        frame.acc = std::move(loaded[i]->acc);
        frame.set_lease_round_from_sums();
        frame.hold_epoch = epoch;
        frame.relative_error = loaded[i]->relative_error.load();
        frame.non_finite = loaded[i]->non_finite.load();
        frame.dirty = false;
        frame.checkpoint_clock.reset();
        frame.history.clear();
    }
    job->row.state = row.state;
    job->row.priority = row.priority;
    job->held = true;
    job->hold_epoch = epoch;
    scheduler_.set_state(job_id, JobState::Cancelled);  // voids any lease of a former hold
    scheduler_.add_job(job_id, row.priority, uint64_t(row.sequence), JobState(row.state),
                       std::move(plans));
    metrics_.job_taken();
    Log("info", "job_taken")
        .kv("job", job_id)
        .kv("epoch", epoch)
        .kv("previous", previous.empty() ? "none" : previous)
        .kv("leases_voided", voided);
}

void JobManager::give_up(JobData& job, const char* why) {
    const std::string& id = job.row.id;
    std::vector<FramePlan> plans;
    for (uint32_t i = 0; i < job.frames.size(); ++i) {
        const FrameProgress p = scheduler_.progress(id, i);
        FramePlan plan;
        plan.target = p.target;
        plan.budget_seconds = job.request.settings().time_budget_seconds();
        plan.elapsed_seconds = p.elapsed_seconds;
        plan.done = p.done;
        for (const Range& r : scheduler_.merged_ranges(id, i)) plan.merged.add(r);
        plans.push_back(std::move(plan));
        FrameData& frame = *job.frames[i];
        std::lock_guard frame_lock(frame.mu);
        frame.acc.reset();
        frame.set_lease_round_from_sums();
        frame.dirty = false;
        frame.hold_epoch = -1;  // a report of the lost hold still merging is not added
    }
    const JobState state = scheduler_.state(id);
    scheduler_.set_state(id, JobState::Cancelled);  // voids its leases: their reports drop
    scheduler_.add_job(id, job.row.priority, uint64_t(job.row.sequence), state, std::move(plans));
    job.held = false;
    Log("warn", "job_given_up").kv("job", id).kv("epoch", job.hold_epoch).kv("reason", why);
}

bool JobManager::still_held(const std::string& job_id) {
    if (!shared_) return true;
    int64_t epoch = 0;
    {
        std::lock_guard lock(mu_);
        auto job = find(job_id);
        if (!job || !job->held) return false;
        epoch = job->hold_epoch;
    }
    bool kept = false;
    try {
        kept = store_.renew_job(job_id, server_id_, epoch, hold_ms(options_));
    } catch (const std::exception& e) {
        Log("error", "hold_renewal_failed").kv("job", job_id).kv("error", e.what());
        return false;  // not written: the database decides who holds the job
    }
    if (!kept) {
        std::lock_guard lock(mu_);
        if (auto job = find(job_id); job && job->held && job->hold_epoch == epoch)
            give_up(*job, "taken by another server");
    }
    return kept;
}

std::string JobManager::report_holder(const std::string& lease_id, size_t* max_value_bytes) {
    if (!shared_ || !is_safe_id(lease_id)) return {};
    std::optional<LeaseRow> lease;
    try {
        lease = store_.find_lease(lease_id);
    } catch (const std::exception& e) {
        Log("error", "store_failed").kv("lease", lease_id).kv("error", e.what());
        return {};
    }
    if (!lease) return {};  // voided (a new holder) or reported: nobody merges it
    auto holder = [&]() -> std::string {
        std::lock_guard lock(mu_);
        auto job = find(lease->job_id);
        if (!job || job->held || !job->row.owner.live || job->row.owner.server == server_id_)
            return {};
        const size_t layers = TechniqueLayers::names(job->settings.layers).size();
        const size_t pixels = size_t(job->row.width) * size_t(job->row.height);
        // The sums and layers, and an adaptive job's two exact sums (int64 per pixel).
        *max_value_bytes = pixels * 3 * sizeof(double) * (2 + layers) +
                           (job->settings.adaptive > 0 ? pixels * 2 * sizeof(int64_t) : 0);
        return job->row.owner.address;
    };
    // The hold as the last sync read it, else as the store has it now (a job taken since).
    // A holder that died since refuses the connection or no longer knows the lease: the
    // report is then dropped, as it always was.
    std::string address = known(lease->job_id) ? holder() : std::string();
    if (address.empty() && learn_job(lease->job_id)) address = holder();
    return address;
}

void JobManager::release_holds() {
    if (!shared_) return;
    std::vector<std::pair<std::string, int64_t>> held;
    {
        std::lock_guard lock(mu_);
        for (auto& [id, job] : jobs_)
            if (job->held) {
                held.emplace_back(id, job->hold_epoch);
                job->held = false;
            }
    }
    for (const auto& [id, epoch] : held)
        store_or_log("job", id, [&] { store_.release_job(id, server_id_, epoch); });
}

}  // namespace render::server
