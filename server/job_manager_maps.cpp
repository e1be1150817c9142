// The dashboard's per-pixel maps of a frame (docs/reference/adaptive-sampling.md, "Seeing it").
#include <mutex>

#include "core/image/exr_io.h"
#include "server/job_manager.h"
#include "server/job_manager_detail.h"

namespace render::server {

using grpc::Status;
using grpc::StatusCode;
using namespace detail;

Status JobManager::pixel_maps(const std::string& job_id, uint32_t index, PixelMaps* maps) {
    std::shared_ptr<JobData> job;
    if (Status status = find_frame(job_id, index, job); !status.ok()) return status;
    FrameData& frame = *job->frames[index];
    {
        std::lock_guard lock(frame.mu);
        if (frame.acc && frame.acc->count() > 0) {
            *maps = render::pixel_maps(frame.acc->result());
            return Status::OK;
        }
    }
    // Done: the sums are gone, the result EXR has what it has (the samples layer of an adaptive
    // job, the variance layer of a job with --layers variance).
    const std::filesystem::path done = frame_files_.result_path(job_id, index);
    if (std::filesystem::exists(done)) {
        try {
            std::map<std::string, std::string> metadata;
            const Image image = read_image(done, &metadata);
            const std::optional<Image> variance = read_exr_layer(done, "variance");
            const std::optional<Image> samples = read_exr_layer(done, "samples");
            *maps = pixel_maps_from_exr(image, variance ? &*variance : nullptr,
                                        samples ? &*samples : nullptr, metadata);
            return Status::OK;
        } catch (const std::exception& e) {
            return Status(StatusCode::INTERNAL, e.what());
        }
    }
    return Status(StatusCode::FAILED_PRECONDITION, "frame " + std::to_string(index) + " of job " +
                                                       job_id + " has no iterations yet");
}

}  // namespace render::server
