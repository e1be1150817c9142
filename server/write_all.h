#pragma once

// Writing a whole buffer to a file descriptor: write(2) may write less than asked, or be
// interrupted by a signal before writing anything, so it is called until all is written.

#include <cstddef>

namespace render::server {

// Writes the `size` bytes at `data` to `fd`. False, with errno saying why, when a write fails.
bool write_all(int fd, const char* data, size_t size);

}  // namespace render::server
