#pragma once

#include <filesystem>
#include <string>

namespace render {

// The whole content of a file. Throws SceneError naming the path if it does not exist, is not
// a regular file or cannot be read.
std::string read_file_bytes(const std::filesystem::path& path);

}  // namespace render
