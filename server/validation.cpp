#include "server/validation.h"

namespace render::server {

std::string check_bundle_path(const std::string& path) {
    if (path.empty()) return "is empty";
    if (path.size() > kMaxPathLength) return "is longer than 1024 characters";
    if (path.front() == '/') return "\"" + path + "\" is absolute";
    if (path.find('\\') != std::string::npos) return "\"" + path + "\" contains a backslash";
    for (char c : path)
        if (static_cast<unsigned char>(c) < 0x20)
            return "\"" + path + "\" contains a control character";
    size_t start = 0;
    while (true) {
        size_t slash = path.find('/', start);
        std::string part =
            path.substr(start, slash == std::string::npos ? std::string::npos : slash - start);
        if (part == "..") return "\"" + path + "\" escapes the job folder (\"..\")";
        if (part.empty()) return "\"" + path + "\" has an empty part";
        if (part == ".") return "\"" + path + "\" has a \".\" part";
        if (slash == std::string::npos) break;
        start = slash + 1;
    }
    return {};
}

bool is_supported_algorithm(const std::string& a) {
    return a == "pt" || a == "volpt" || a == "lt" || a == "bpt" || a == "ppm" || a == "bpm" ||
           a == "vcm";
}

bool is_safe_id(const std::string& id) {
    if (id.empty() || id.size() > 64) return false;
    for (char c : id)
        if (!((c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
              c == '-' || c == '_'))
            return false;
    return true;
}

}  // namespace render::server
