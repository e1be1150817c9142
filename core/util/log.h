#pragma once

// Structured log lines on stderr, one per event, shared by the server and the workers:
// `ts=... level=info event=lease job=... worker=...`. Values with spaces, quotes or '=' are
// quoted. Usage: log_info("lease").kv("job", id).kv("first", 1);  (written when destroyed)

#include <sstream>
#include <string>
#include <string_view>

namespace render {

class Log {
  public:
    Log(std::string_view level, std::string_view event);
    ~Log();
    Log(const Log&) = delete;
    Log& operator=(const Log&) = delete;

    Log& kv(std::string_view key, std::string_view value);
    Log& kv(std::string_view key, const std::string& value) {
        return kv(key, std::string_view(value));
    }
    Log& kv(std::string_view key, const char* value) { return kv(key, std::string_view(value)); }
    template <typename T>
    Log& kv(std::string_view key, const T& value) {
        std::ostringstream s;
        s << value;
        return kv(key, std::string_view(s.str()));
    }

  private:
    std::string line_;
};

inline Log log_info(std::string_view event) {
    return Log("info", event);
}
inline Log log_warn(std::string_view event) {
    return Log("warn", event);
}
inline Log log_error(std::string_view event) {
    return Log("error", event);
}

}  // namespace render
