#pragma once

// The limits of one render job, the same for `render`, the client and the server: the
// iteration count, the time budget and the film size. The server also limits what a request
// may carry (server/validation.h).

#include <cstdint>
#include <string>

namespace render {

inline constexpr uint64_t kMaxIterations = 10000000;
inline constexpr double kMaxTimeBudgetSeconds = 30 * 24 * 3600.0;  // 30 days
// A target error (--target-error, RenderSettings.target_error) is in (0, kMaxTargetError] and
// stops a frame no earlier than after kMinTargetErrorIterations iterations: the odd/even
// estimate of fewer is too rough to stop on (with one iteration there is none).
inline constexpr double kMaxTargetError = 10.0;
inline constexpr uint64_t kMinTargetErrorIterations = 4;
// Largest total of iterations over a job's frames (iterations x frames): 10^8, e.g. 100000
// iterations of each of 1000 frames.
inline constexpr uint64_t kMaxJobIterations = 100000000;
// "" if iterations x frames is within kMaxJobIterations, else the message naming the limit.
std::string check_job_iterations(uint64_t iterations, uint64_t frames);
// Largest film side: an 8192^2 frame's two float64 sums take 3.2 GB at the server.
inline constexpr int kMaxFilmResolution = 8192;

// Checked command-line values (UsageError naming `flag`): iterations in [1, kMaxIterations],
// a time budget in (0, kMaxTimeBudgetSeconds].
uint64_t parse_iterations(const std::string& flag, const std::string& text);
double parse_time_budget(const std::string& flag, const std::string& text);
double parse_target_error(const std::string& flag, const std::string& text);

}  // namespace render
