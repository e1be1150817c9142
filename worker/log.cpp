#include "worker/log.h"

#include <chrono>
#include <cstdio>
#include <ctime>
#include <mutex>

namespace render::service {

namespace {
std::mutex log_mutex;

std::string now_iso() {
    auto now = std::chrono::system_clock::now();
    std::time_t t = std::chrono::system_clock::to_time_t(now);
    int ms =
        int(std::chrono::duration_cast<std::chrono::milliseconds>(now.time_since_epoch()).count() %
            1000);
    std::tm tm{};
    gmtime_r(&t, &tm);
    char buf[80];
    std::snprintf(buf, sizeof buf, "%04d-%02d-%02dT%02d:%02d:%02d.%03dZ", tm.tm_year + 1900,
                  tm.tm_mon + 1, tm.tm_mday, tm.tm_hour, tm.tm_min, tm.tm_sec, ms);
    return buf;
}
}  // namespace

LogLine::LogLine(const char* level, const char* event) {
    line_ = "time=" + now_iso() + " level=" + level + " event=" + event;
}

LogLine::~LogLine() {
    std::lock_guard<std::mutex> lock(log_mutex);
    std::fprintf(stderr, "%s\n", line_.c_str());
    std::fflush(stderr);
}

void LogLine::add(const char* key, const std::string& value) {
    bool quote = value.empty() || value.find_first_of(" \t\"=") != std::string::npos;
    line_ += ' ';
    line_ += key;
    line_ += '=';
    if (!quote) {
        line_ += value;
        return;
    }
    line_ += '"';
    for (char c : value) {
        if (c == '"' || c == '\\') line_ += '\\';
        line_ += c == '\n' ? ' ' : c;
    }
    line_ += '"';
}

}  // namespace render::service
