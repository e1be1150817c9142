#pragma once

// Checks of untrusted request fields. Each returns an empty string when the value is fine,
// otherwise a message naming the field.

#include <cstdint>
#include <string>

namespace render::server {

// Limits of a job (see issue 4: input limits).
inline constexpr uint64_t kMaxIterations = 10000000;
inline constexpr uint32_t kMaxResolution = 8192;
inline constexpr size_t kMaxFrames = 1000;
inline constexpr size_t kMaxBundleFiles = 10000;
inline constexpr uint64_t kMaxAssetSize = 4ull << 30;    // 4 GiB per asset
inline constexpr uint64_t kMaxBundleSize = 16ull << 30;  // 16 GiB per job
inline constexpr double kMaxTimeBudgetSeconds = 30 * 24 * 3600.0;
inline constexpr size_t kMaxPathLength = 1024;

// A bundle path: relative, forward slashes, no "..", ".", empty or absolute parts.
std::string check_bundle_path(const std::string& path);

// One of pt, lt, bpt, ppm, bpm, vcm.
bool is_supported_algorithm(const std::string& algorithm);

// A job id as the server makes them (letters, digits, '-'), so that it is safe in a path.
bool is_safe_id(const std::string& id);

}  // namespace render::server
