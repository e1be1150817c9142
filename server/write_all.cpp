#include "server/write_all.h"

#include <unistd.h>

#include <cerrno>

namespace render::server {

bool write_all(int fd, const char* data, size_t size) {
    while (size > 0) {
        const ssize_t n = ::write(fd, data, size);
        if (n < 0 && errno == EINTR) continue;
        if (n <= 0) {
            if (n == 0) errno = EIO;  // nothing written and no error: do not spin
            return false;
        }
        data += n;
        size -= size_t(n);
    }
    return true;
}

}  // namespace render::server
