#pragma once

// Submission checking: what SubmitJob decides about a request once its bundle's files are in
// the job's scene folder, before the job exists. Frame 0's scene gives the settings (resolved
// to the complete options the algorithm reads, docs/design/architecture.md) and the film size;
// every other distinct frame's scene must load and suit the algorithm (docs/guide/service.md,
// "Animations"). No state of the server is read or changed: a bad request gets a clear error.

#include <grpcpp/grpcpp.h>

#include <cstdint>
#include <exception>
#include <filesystem>
#include <functional>
#include <map>
#include <optional>
#include <string>

#include "render.pb.h"

namespace render::server {

namespace v1 = ::render::v1;

// The defines frame `frame` renders with: the job's, overridden by the frame's own.
std::map<std::string, std::string> frame_defines(const v1::SubmitJobRequest& request,
                                                 uint32_t frame);

// Every bundle file names an uploaded asset of the size it declares (0: any).
// `asset_size`: an asset's stored size, nullopt when it is not in the store.
grpc::Status check_bundle_assets(
    const v1::SubmitJobRequest& request,
    const std::function<std::optional<uint64_t>(const std::string& sha256)>& asset_size);

struct ValidatedSubmission {
    // The request with its settings resolved: the algorithm, its complete options, the
    // iterations (the scene's sample_count when neither they nor a time budget were given)
    // and the film size.
    v1::SubmitJobRequest request;
    uint32_t frames = 1;
    double validate_seconds = 0;  // spent loading scenes
};

// A refused submission: the status the client gets, and what the server logs of it.
struct SubmissionRejection {
    grpc::Status status;
    // The log's reason ("validation_budget", "scene" or "load"); null for bad settings,
    // which are the request's fault and not logged.
    const char* log_reason = nullptr;
    int64_t frame = -1;  // the frame whose scene failed (-1: none)
    std::string error;   // the error with the bundle's paths
};

struct SubmissionCheck {
    std::optional<ValidatedSubmission> job;  // set when accepted
    SubmissionRejection rejection;           // otherwise
};

inline constexpr const char* kValidationBudgetReason = "validation_budget";

// Checks `request` against its scene files in `scene_dir` (bundle paths resolve there and
// cannot leave it). An animation whose scene loads would take longer than
// `validation_seconds` (estimated from the frames loaded so far) is refused with
// RESOURCE_EXHAUSTED before the time is spent; scenes that need more memory than the machine
// has available are refused too.
SubmissionCheck check_submission(const v1::SubmitJobRequest& request,
                                 const std::filesystem::path& scene_dir, double validation_seconds);

// `error`, thrown while `frame`'s scene was loaded or checked (-1: before any), as the client
// and the log get it: a bad setting as such, scene and load errors prefixed, files named as in
// the client's bundle, and in an animation the failing frame and its overrides first.
SubmissionRejection submission_error(const v1::SubmitJobRequest& request,
                                     const std::filesystem::path& scene_dir, int64_t frame,
                                     const std::exception& error);

}  // namespace render::server
