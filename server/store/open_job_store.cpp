#include "server/store/open_job_store.h"

#include <stdexcept>

#include "server/store/postgres_job_store.h"
#include "server/store/sqlite_job_store.h"

namespace render::server {

namespace {

bool starts_with(const std::string& s, const char* prefix) {
    return s.rfind(prefix, 0) == 0;
}

bool is_postgres_url(const std::string& location) {
    return starts_with(location, "postgresql://") || starts_with(location, "postgres://");
}

}  // namespace

bool is_store_url(const std::string& location) {
    return is_postgres_url(location) || starts_with(location, "sqlite:");
}

std::string sqlite_url_path(const std::string& location) {
    if (!starts_with(location, "sqlite:")) return "";
    std::string path = location.substr(7);
    // sqlite:///abs/path and sqlite://relative read as the path after the slashes' authority.
    if (starts_with(path, "//")) path = path.substr(2);
    return path;
}

std::unique_ptr<JobStore> open_job_store(const std::string& url, size_t connections) {
    if (is_postgres_url(url)) return std::make_unique<PostgresJobStore>(url, connections);
    if (starts_with(url, "sqlite:")) {
        const std::string path = sqlite_url_path(url);
        if (path.empty()) throw std::invalid_argument("sqlite: names no database file");
        return std::make_unique<SqliteJobStore>(path);
    }
    throw std::invalid_argument("not a store URL (postgresql://... or sqlite:FILE): " +
                                redact_store_url(url));
}

std::string redact_store_url(const std::string& url) {
    std::string out = url;
    // user:password@ in the authority.
    const size_t scheme = out.find("://");
    if (scheme != std::string::npos) {
        const size_t start = scheme + 3;
        const size_t end = out.find_first_of("/?", start);
        const size_t at = out.rfind('@', end == std::string::npos ? out.size() : end);
        if (at != std::string::npos && at >= start) {
            const size_t colon = out.find(':', start);
            if (colon != std::string::npos && colon < at)
                out.replace(colon + 1, at - colon - 1, "***");
        }
    }
    // password=... among the query parameters.
    for (size_t p = out.find("password="); p != std::string::npos;
         p = out.find("password=", p + 1)) {
        const size_t value = p + 9;
        const size_t end = out.find('&', value);
        out.replace(value, (end == std::string::npos ? out.size() : end) - value, "***");
    }
    return out;
}

}  // namespace render::server
