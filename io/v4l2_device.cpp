#include "io/v4l2_device.hpp"

#include <fcntl.h>
#include <poll.h>
#include <sys/ioctl.h>
#include <sys/mman.h>
#include <unistd.h>

#include <cerrno>

namespace io {
namespace {

class SystemV4l2Device final : public V4l2Device {
  public:
    ~SystemV4l2Device() override { close(); }

    int open(const std::string& path) override {
        close();
        fd_ = ::open(path.c_str(), O_RDWR | O_NONBLOCK | O_CLOEXEC);
        return fd_ < 0 ? -errno : 0;
    }

    int ioctl(unsigned long request, void* arg) override {
        if (fd_ < 0) return -EBADF;
        int rc;
        do {
            rc = ::ioctl(fd_, request, arg);
        } while (rc < 0 && errno == EINTR);
        return rc < 0 ? -errno : 0;
    }

    void* map(std::size_t length, std::int64_t offset, int* errorOut) override {
        void* p = ::mmap(nullptr, length, PROT_READ | PROT_WRITE, MAP_SHARED, fd_,
                         static_cast<off_t>(offset));
        if (p == MAP_FAILED) {
            if (errorOut) *errorOut = -errno;
            return nullptr;
        }
        return p;
    }

    int unmap(void* address, std::size_t length) override {
        return ::munmap(address, length) == 0 ? 0 : -errno;
    }

    int waitWritable(int timeoutMs) override {
        pollfd p{fd_, POLLOUT, 0};
        int rc;
        do {
            rc = ::poll(&p, 1, timeoutMs);
        } while (rc < 0 && errno == EINTR);
        if (rc < 0) return -errno;
        if (rc > 0 && (p.revents & (POLLERR | POLLNVAL))) return -EIO;
        return rc > 0 ? 1 : 0;
    }

    void close() override {
        if (fd_ >= 0) ::close(fd_);
        fd_ = -1;
    }

  private:
    int fd_ = -1;
};

}  // namespace

std::unique_ptr<V4l2Device> makeSystemV4l2Device() {
    return std::make_unique<SystemV4l2Device>();
}

}  // namespace io
