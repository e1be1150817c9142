#include "service/server_list.h"

#include <algorithm>
#include <stdexcept>

namespace render::service {

std::vector<std::string> split_server_list(const std::string& list) {
    std::vector<std::string> out;
    size_t start = 0;
    for (;;) {
        const size_t comma = list.find(',', start);
        std::string entry = list.substr(start, comma == std::string::npos ? comma : comma - start);
        const size_t first = entry.find_first_not_of(" \t");
        const size_t last = entry.find_last_not_of(" \t");
        entry = first == std::string::npos ? "" : entry.substr(first, last - first + 1);
        if (entry.empty())
            throw std::invalid_argument("the server list \"" + list + "\" has an empty entry");
        const size_t colon = entry.rfind(':');
        if (colon == std::string::npos || colon == 0 || colon + 1 == entry.size() ||
            entry.find_first_not_of("0123456789", colon + 1) != std::string::npos)
            throw std::invalid_argument("\"" + entry + "\" is not HOST:PORT");
        if (std::find(out.begin(), out.end(), entry) != out.end())
            throw std::invalid_argument("\"" + entry + "\" is twice in the server list");
        out.push_back(entry);
        if (comma == std::string::npos) break;
        start = comma + 1;
    }
    return out;
}

}  // namespace render::service
