// The job manager's frames: checkpoints written when due, complete frames finished into
// their EXR, and the images clients and the dashboard fetch (server/frame_files.h).

#include "server/job_manager.h"

#include <map>
#include <mutex>
#include <set>

#include "core/image/exr_io.h"
#include "core/util/log.h"
#include "server/job_manager_detail.h"

namespace render::server {

namespace fs = std::filesystem;
using grpc::Status;
using grpc::StatusCode;
using namespace detail;

void JobManager::advance() {
    // First: a frame whose last round left no pixel active completes in this same call.
    advance_rounds();
    std::vector<std::pair<std::string, uint32_t>> complete;
    std::vector<std::string> expired;
    {
        std::lock_guard lock(mu_);
        for (const auto& done : scheduler_.tick())
            // Another server holds the job: it finishes the frame (this one has no sums).
            if (auto job = find(done.first); job && holds(*job)) complete.push_back(done);
        for (const LeaseGrant& grant : scheduler_.take_expired()) {
            lease_lost(grant);
            expired.push_back(grant.lease_id);
        }
        fail_memory_blocked();
    }
    // On a shared store an expired lease's row goes (claim_lease would refuse its range when
    // it is leased again).
    if (shared_)
        for (const std::string& id : expired)
            store_or_log("lease", id, [&] { store_.delete_lease(id); });
    for (const auto& [job_id, frame] : complete) finish_frame(job_id, frame);
}

void JobManager::flush_checkpoints(bool all) {
    struct Due {
        std::shared_ptr<JobData> job;
        std::string id;
        uint32_t index;
        double elapsed;
    };
    std::vector<Due> due;
    {
        std::lock_guard lock(mu_);
        for (const auto& [id, job] : jobs_) {
            if (is_terminal(scheduler_.state(id)) || !holds(*job)) continue;
            for (uint32_t i = 0; i < job->frames.size(); ++i)
                if (job->frames[i]->dirty.load())
                    due.push_back({job, id, i, scheduler_.progress(id, i).elapsed_seconds});
        }
    }
    const TimePoint now = clock_();
    std::set<std::string> renewed;
    for (const Due& d : due) {
        FrameData& frame = *d.job->frames[d.index];
        {
            std::lock_guard lock(frame.mu);
            if (!frame.dirty || !frame.acc) continue;
            if (!all && !frame_files_.checkpoint_due(frame, now)) continue;
        }
        // On a shared store a checkpoint is written only within a hold just renewed: the
        // server that would take the job over waits for the hold to run out.
        if (shared_ && !renewed.count(d.id)) {
            if (!still_held(d.id)) continue;
            renewed.insert(d.id);
        }
        std::lock_guard lock(frame.mu);
        if (!frame.dirty || !frame.acc) continue;
        frame_files_.save_checkpoint(d.id, d.index, frame, d.elapsed,
                                     all ? "shutdown" : "interval");
    }
}

void JobManager::checkpoint_all() {
    flush_checkpoints(true);
    {
        std::lock_guard lock(mu_);
        for (const auto& [id, job] : jobs_) {
            if (is_terminal(scheduler_.state(id)) || !holds(*job)) continue;
            for (uint32_t i = 0; i < job->frames.size(); ++i) {
                FrameProgress p = scheduler_.progress(id, i);
                if (p.done) continue;
                store_or_log("job", id,
                             [&] { store_.update_frame(id, i, false, p.elapsed_seconds); });
            }
        }
    }
    delete_reported_leases();
    // Written: another server may take the jobs over from these checkpoints at once.
    release_holds();
    Log("info", "checkpointed");
}

void JobManager::finish_frame(const std::string& job_id, uint32_t index) {
    std::lock_guard finish_lock(finish_mu_);
    std::shared_ptr<JobData> job;
    FrameProgress progress;
    {
        std::lock_guard lock(mu_);
        job = find(job_id);
        progress = scheduler_.progress(job_id, index);
    }
    if (!job) return;
    // Another server took the job meanwhile: it writes the frame.
    if (!still_held(job_id)) return;
    FrameData& frame = *job->frames[index];
    std::string error;
    std::vector<Range> ranges;  // what the EXR holds
    int64_t epoch = 0;          // the hold the frame's sums belong to: the store's write fence
    {
        std::lock_guard lock(frame.mu);
        epoch = frame.hold_epoch;
        if (!frame.acc) {
            error = "frame " + std::to_string(index) + " has no merged sums";
        } else {
            const std::map<std::string, std::string> metadata = frame_metadata(
                job->request, job->settings, job_id, index, *frame.acc, progress.elapsed_seconds);
            try {
                write_frame_exr(frame_files_.result_path(job_id, index), frame.acc->average(),
                                metadata, frame.acc->layer_averages());
                frame.relative_error = frame.acc->relative_error();
                ranges = frame.acc->ranges().ranges();
                frame.acc.reset();
                frame.dirty = false;
            } catch (const std::exception& e) {
                error = std::string("cannot write the result: ") + e.what();
            }
        }
    }
    std::lock_guard lock(mu_);
    if (!error.empty()) {
        Log("error", "frame_failed").kv("job", job_id).kv("frame", index).kv("error", error);
        set_state(*job, JobState::Failed, error);
        return;
    }
    bool job_done = scheduler_.finish_frame(job_id, index);
    store_or_log("job", job_id, [&] {
        store_.save_frame(job_id, index, ranges, true, progress.elapsed_seconds, epoch);
        frame_files_.remove_checkpoints(job_id, index);
    });
    Log("info", "frame_done")
        .kv("job", job_id)
        .kv("frame", index)
        .kv("iterations", progress.merged)
        .kv("seconds", progress.elapsed_seconds)
        .kv("relative_error", frame.relative_error.load());
    if (job_done) {
        set_state(*job, JobState::Done, "");
        Log("info", "job_done").kv("job", job_id);
    }
}

Status JobManager::result_file(const v1::FetchResultRequest& request, fs::path* file,
                               bool* temporary) {
    std::shared_ptr<JobData> job;
    FrameProgress progress;
    if (shared_ && !known(request.job_id())) learn_job(request.job_id());
    {
        std::lock_guard lock(mu_);
        job = find(request.job_id());
        if (!job) return job_not_found(request.job_id());
        if (request.frame() >= job->frames.size())
            return frame_not_found(request.job_id(), request.frame(), job->frames.size());
        progress = scheduler_.progress(request.job_id(), request.frame());
    }
    *temporary = false;
    if (progress.done) {
        *file = frame_files_.result_path(request.job_id(), request.frame());
        if (!fs::exists(*file))
            return Status(StatusCode::NOT_FOUND, "the result file of job " + request.job_id() +
                                                     " frame " + std::to_string(request.frame()) +
                                                     " is missing");
        return Status::OK;
    }
    if (!request.preview())
        return Status(StatusCode::FAILED_PRECONDITION,
                      "frame " + std::to_string(request.frame()) + " of job " + request.job_id() +
                          " is not done (" + std::to_string(progress.merged) +
                          " iterations so far); ask for a preview");
    FrameData& frame = *job->frames[request.frame()];
    std::lock_guard lock(frame.mu);
    if (!frame.acc || frame.acc->count() == 0) {
        // It may have finished meanwhile.
        fs::path done = frame_files_.result_path(request.job_id(), request.frame());
        if (fs::exists(done)) {
            *file = done;
            return Status::OK;
        }
        return Status(StatusCode::FAILED_PRECONDITION, "frame " + std::to_string(request.frame()) +
                                                           " of job " + request.job_id() +
                                                           " has no iterations yet");
    }
    *file = assets_.tmp_dir() / ("preview-" + request.job_id() + "-" +
                                 std::to_string(request.frame()) + "-" + random_hex(8) + ".exr");
    std::map<std::string, std::string> metadata =
        frame_metadata(job->request, job->settings, request.job_id(), request.frame(), *frame.acc,
                       progress.elapsed_seconds);
    metadata["render:preview"] = "1";
    try {
        write_frame_exr(*file, frame.acc->average(), metadata, frame.acc->layer_averages());
    } catch (const std::exception& e) {
        return Status(StatusCode::INTERNAL, std::string("cannot write the preview: ") + e.what());
    }
    *temporary = true;
    return Status::OK;
}

Status JobManager::preview_image(const std::string& job_id, uint32_t index, Image* image) {
    std::shared_ptr<JobData> job;
    FrameProgress progress;
    {
        std::lock_guard lock(mu_);
        job = find(job_id);
        if (!job) return job_not_found(job_id);
        if (index >= job->frames.size()) return frame_not_found(job_id, index, job->frames.size());
        progress = scheduler_.progress(job_id, index);
    }
    FrameData& frame = *job->frames[index];
    {
        std::lock_guard lock(frame.mu);
        if (frame.acc && frame.acc->count() > 0) {
            *image = frame.acc->average();
            return Status::OK;
        }
    }
    const fs::path done = frame_files_.result_path(job_id, index);
    if (fs::exists(done)) {
        try {
            *image = read_image(done);
            return Status::OK;
        } catch (const std::exception& e) {
            return Status(StatusCode::INTERNAL, e.what());
        }
    }
    return Status(StatusCode::FAILED_PRECONDITION, "frame " + std::to_string(index) + " of job " +
                                                       job_id + " has no iterations yet");
}

Status JobManager::find_frame(const std::string& job_id, uint32_t index,
                              std::shared_ptr<JobData>& job) {
    std::lock_guard lock(mu_);
    job = find(job_id);
    if (!job) return job_not_found(job_id);
    if (index >= job->frames.size()) return frame_not_found(job_id, index, job->frames.size());
    return Status::OK;
}

Status JobManager::error_history(const std::string& job_id, uint32_t index,
                                 std::vector<ErrorPoint>* points) {
    std::shared_ptr<JobData> job;
    if (Status status = find_frame(job_id, index, job); !status.ok()) return status;
    FrameData& frame = *job->frames[index];
    std::lock_guard lock(frame.mu);
    *points = frame.history;
    return Status::OK;
}

}  // namespace render::server
