#pragma once

// Structured log lines on stderr: `time=... level=info event=lease job=... frame=0`.

#include <sstream>
#include <string>

namespace render::service {

class LogLine {
  public:
    LogLine(const char* level, const char* event);
    ~LogLine();  // writes the line
    LogLine(const LogLine&) = delete;
    LogLine& operator=(const LogLine&) = delete;

    template <typename T>
    LogLine& kv(const char* key, const T& value) {
        std::ostringstream s;
        s << value;
        add(key, s.str());
        return *this;
    }

  private:
    void add(const char* key, const std::string& value);
    std::string line_;
};

inline LogLine log_info(const char* event) {
    return LogLine("info", event);
}
inline LogLine log_warn(const char* event) {
    return LogLine("warn", event);
}
inline LogLine log_error(const char* event) {
    return LogLine("error", event);
}

}  // namespace render::service
