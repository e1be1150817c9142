#pragma once

// Checks of untrusted request fields, each with a message naming the field.

#include <cstdint>
#include <string>

#include <grpcpp/grpcpp.h>

#include "render.pb.h"

namespace render::server {

// Limits of a request (the limits of the render itself, shared with `render` and the client,
// are in core/render/job_limits.h).
inline constexpr size_t kMaxFrames = 1000;
inline constexpr size_t kMaxBundleFiles = 10000;
inline constexpr uint64_t kMaxAssetSize = 4ull << 30;    // 4 GiB per asset
inline constexpr uint64_t kMaxBundleSize = 16ull << 30;  // 16 GiB per job
// The defaults of server --max-job-assets (a job's bundle in all, at most kMaxBundleSize) and
// --max-store-size (every asset the store keeps).
inline constexpr uint64_t kDefaultMaxJobAssets = kMaxBundleSize;
inline constexpr uint64_t kDefaultMaxStoreSize = 100ull << 30;  // 100 GiB
inline constexpr size_t kMaxPathLength = 1024;
// WatchJob streams open at once on a server: each holds one of the server's threads and polls
// the job manager for as long as its job runs (1000 streams took 1000 threads and made GetJob
// take 2 s). Past it a watch is refused with RESOURCE_EXHAUSTED; clients then poll GetJob.
inline constexpr size_t kMaxWatchStreams = 256;

// A bundle path: relative, forward slashes, no "..", ".", empty or absolute parts.
std::string check_bundle_path(const std::string& path);

// Everything about a SubmitJobRequest that can be checked without its assets and scene:
// name, settings (algorithm, limits, options against the render options table), defines,
// frames and the bundle's paths and sizes. INVALID_ARGUMENT or RESOURCE_EXHAUSTED naming the
// field. `max_job_assets`: the bundle's total size limit (server --max-job-assets).
grpc::Status check_submit_request(const v1::SubmitJobRequest& request,
                                  uint64_t max_job_assets = kDefaultMaxJobAssets);

// A job id as the server makes them (letters, digits, '-'), so that it is safe in a path.
bool is_safe_id(const std::string& id);

}  // namespace render::server
