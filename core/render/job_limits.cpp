#include "core/render/job_limits.h"

#include "core/util/arguments.h"

namespace render {

uint64_t parse_iterations(const std::string& flag, const std::string& text) {
    const int64_t n = parse_number<int64_t>(flag, text);
    if (n < 1 || uint64_t(n) > kMaxIterations)
        throw UsageError(flag + " must be in [1, " + std::to_string(kMaxIterations) + "], got " +
                         text);
    return uint64_t(n);
}

double parse_time_budget(const std::string& flag, const std::string& text) {
    const double s = parse_number<double>(flag, text);
    if (!(s > 0) || s > kMaxTimeBudgetSeconds)
        throw UsageError(flag + " must be in (0, " +
                         std::to_string(int64_t(kMaxTimeBudgetSeconds)) + "] seconds, got " + text);
    return s;
}

double parse_target_error(const std::string& flag, const std::string& text) {
    const double e = parse_number<double>(flag, text);
    if (!(e > 0) || e > kMaxTargetError)
        throw UsageError(flag + " must be a relative error in (0, " +
                         std::to_string(int(kMaxTargetError)) + "], got " + text);
    return e;
}

std::string check_job_iterations(uint64_t iterations, uint64_t frames) {
    if (frames == 0 || iterations <= kMaxJobIterations / frames) return {};
    return "settings.iterations x frames: " + std::to_string(iterations) + " x " +
           std::to_string(frames) + " exceeds the limit of " + std::to_string(kMaxJobIterations) +
           " iterations per job (kMaxJobIterations)";
}

}  // namespace render
