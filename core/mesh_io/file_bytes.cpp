#include "core/mesh_io/file_bytes.h"

#include <fstream>
#include <sstream>
#include <system_error>

#include "core/base/error.h"
#include "core/base/memory_budget.h"

namespace render {

std::string read_file_bytes(const std::filesystem::path& path) {
    std::error_code ec;
    if (!std::filesystem::exists(path, ec)) throw SceneError(path.string() + ": file not found");
    if (!std::filesystem::is_regular_file(path, ec))
        throw SceneError(path.string() + ": not a regular file");
    charge_file_contents(path);
    std::ifstream in(path, std::ios::binary);
    if (!in) throw SceneError(path.string() + ": cannot open file");
    std::ostringstream out;
    out << in.rdbuf();
    if (in.bad()) throw SceneError(path.string() + ": read error");
    return std::move(out).str();
}

}  // namespace render
