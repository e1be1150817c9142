// The job manager's adaptive rounds (docs/reference/adaptive-sampling.md, "The service"): a
// round's leases carry its mask, which workers fetch once; at a round's end, when every one of
// its iterations is merged, the next round's mask is computed from the merged exact sums with
// the function `render` uses (adaptive_round_mask), so that the cluster's image is `render`'s.

#include <algorithm>

#include "core/util/log.h"
#include "server/job_manager.h"
#include "server/job_manager_detail.h"

namespace render::server {

using grpc::Status;
using grpc::StatusCode;
using namespace detail;

void JobManager::advance_rounds() {
    std::vector<std::pair<std::shared_ptr<JobData>, uint32_t>> due;
    {
        std::lock_guard lock(mu_);
        for (const auto& [job_id, index] : scheduler_.round_boundaries())
            if (auto job = find(job_id); job && holds(*job)) due.emplace_back(job, index);
    }
    for (const auto& [job, index] : due) {
        FrameData& frame = *job->frames[index];
        uint64_t round = 0, active = 0, round_end = 0;
        std::string sha256;
        {
            std::lock_guard lock(frame.mu);
            // Another call took this round's mask meanwhile (its scheduler update follows).
            if (!frame.acc || !frame.acc->round_complete()) continue;
            std::vector<uint8_t> mask = frame.acc->next_round_mask(job->settings);
            round = frame.acc->round() + 1;
            for (uint8_t m : mask) active += m;
            // With no pixel left the frame ends here, at the same iteration count as `render`;
            // the sums stay at their round, so a restart computes the same empty mask again.
            if (active > 0) {
                frame.acc->start_next_round(std::move(mask));
                round_end = frame.acc->rounds().end(round);
                sha256 = frame.acc->mask_sha256();
                frame.dirty = true;  // the next checkpoint holds the new round's mask
                if (!frame.checkpoint_clock) frame.checkpoint_clock = clock_();
            }
        }
        std::lock_guard lock(mu_);
        if (find(job->row.id) != job || !holds(*job)) continue;
        if (active > 0) {
            // Leases of the round name its mask from now on (fill_lease_mask).
            frame.lease_round = round;
            frame.lease_mask_sha256 = sha256;
            frame.lease_active_pixels = active;
            scheduler_.open_round(job->row.id, index, round_end);
        } else
            scheduler_.close_frame(job->row.id, index);
        Log("info", "adaptive_round")
            .kv("job", job->row.id)
            .kv("frame", index)
            .kv("round", round)
            .kv("active_pixels", active)
            .kv("end", round_end);
    }
}

bool JobManager::fill_lease_mask(const JobData& job, const LeaseGrant& grant, v1::Lease* lease) {
    if (job.settings.adaptive <= 0) return true;
    const uint64_t round = AdaptiveRounds(job.settings).round_of(grant.range.first);
    lease->set_adaptive_round(round);
    if (round == 0) return true;
    const FrameData& frame = *job.frames[grant.frame];
    if (frame.lease_round != round) return false;
    lease->set_adaptive_mask_sha256(frame.lease_mask_sha256);
    lease->set_adaptive_active_pixels(frame.lease_active_pixels);
    return true;
}

Status JobManager::fetch_mask(const v1::FetchMaskRequest& request, std::string* packed) {
    std::optional<LeaseGrant> grant;
    std::shared_ptr<JobData> job;
    {
        std::lock_guard lock(mu_);
        grant = scheduler_.find_lease(request.lease_id());
        if (!grant || grant->worker_id != request.worker_id())
            return Status(StatusCode::NOT_FOUND,
                          "lease \"" + request.lease_id().substr(0, 80) + "\" not found");
        job = find(grant->job_id);
        if (!job || job->settings.adaptive <= 0 || grant->frame >= job->frames.size())
            return Status(StatusCode::FAILED_PRECONDITION,
                          "lease " + grant->lease_id + " is not of an adaptive job");
    }
    const uint64_t round = AdaptiveRounds(job->settings).round_of(grant->range.first);
    // Outside mu_: a report merging into the frame holds frame.mu meanwhile.
    FrameData& frame = *job->frames[grant->frame];
    std::lock_guard frame_lock(frame.mu);
    if (round == 0 || !frame.acc || frame.acc->round() != round)
        return Status(StatusCode::FAILED_PRECONDITION, "lease " + grant->lease_id +
                                                           " is of round " + std::to_string(round) +
                                                           ", which has no mask or is over");
    *packed = frame.acc->packed_mask();
    return Status::OK;
}

}  // namespace render::server
