#pragma once

// Several server addresses in one flag (`--server A:1,B:2`, docs/guide/service.md, "Several
// servers"): workers and clients use the first that answers and fail over to the next.

#include <string>
#include <vector>

namespace render::service {

// The addresses of a comma-separated list, in order, blanks around each trimmed. Throws
// std::invalid_argument naming the problem for an empty list or entry, an entry without
// HOST:PORT's colon or port, or the same address twice.
std::vector<std::string> split_server_list(const std::string& list);

}  // namespace render::service
