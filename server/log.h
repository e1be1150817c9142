#pragma once

// Structured log lines on stderr: `ts=... level=info event=lease job=... worker=...`.
// Usage: Log("info", "lease").kv("job", id).kv("first", 1);  (written when destroyed)

#include <sstream>
#include <string>
#include <string_view>

namespace render::server {

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

}  // namespace render::server
