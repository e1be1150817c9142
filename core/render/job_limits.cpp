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

}  // namespace render
