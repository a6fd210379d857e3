#include "io/text_file.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

namespace io {

int readTextFile(const std::string& path, std::string& text, std::string* error) {
    auto fail = [&](int err, const std::string& why) {
        if (error) *error = why;
        return -err;
    };
    const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd < 0) {
        const int err = errno;
        return fail(err, std::string("cannot open: ") + std::strerror(err));
    }
    struct stat st {};
    if (::fstat(fd, &st) == 0 && S_ISDIR(st.st_mode)) {
        ::close(fd);
        return fail(EISDIR, "is a folder, not a file");
    }
    text.clear();
    char buf[65536];
    for (;;) {
        const ssize_t n = ::read(fd, buf, sizeof buf);
        if (n == 0) break;
        if (n < 0) {
            if (errno == EINTR) continue;
            const int err = errno;
            ::close(fd);
            return fail(err, std::string("read failed: ") + std::strerror(err));
        }
        text.append(buf, static_cast<std::size_t>(n));
    }
    ::close(fd);
    return 0;
}

}  // namespace io
