#include "core/util/log.h"

#include <chrono>
#include <cstdio>
#include <ctime>
#include <mutex>

namespace render {

namespace {
std::mutex& log_mutex() {
    static std::mutex mu;
    return mu;
}
}  // namespace

Log::Log(std::string_view level, std::string_view event) {
    auto now = std::chrono::system_clock::now();
    std::time_t t = std::chrono::system_clock::to_time_t(now);
    int ms =
        int(std::chrono::duration_cast<std::chrono::milliseconds>(now.time_since_epoch()).count() %
            1000);
    std::tm tm{};
    gmtime_r(&t, &tm);
    char buf[64];
    std::snprintf(buf, sizeof buf, "ts=%04d-%02d-%02dT%02d:%02d:%02d.%03dZ", tm.tm_year + 1900,
                  tm.tm_mon + 1, tm.tm_mday, tm.tm_hour, tm.tm_min, tm.tm_sec, ms);
    line_ = buf;
    kv("level", level);
    kv("event", event);
}

Log& Log::kv(std::string_view key, std::string_view value) {
    line_ += ' ';
    line_ += key;
    line_ += '=';
    bool quote = value.empty() || value.find_first_of(" \"=\t\n") != std::string_view::npos;
    if (!quote) {
        line_ += value;
        return *this;
    }
    line_ += '"';
    for (char c : value) {
        if (c == '"' || c == '\\') line_ += '\\';
        if (c == '\n') {
            line_ += "\\n";
            continue;
        }
        line_ += c;
    }
    line_ += '"';
    return *this;
}

Log::~Log() {
    std::lock_guard lock(log_mutex());
    std::fprintf(stderr, "%s\n", line_.c_str());
    std::fflush(stderr);
}

}  // namespace render
