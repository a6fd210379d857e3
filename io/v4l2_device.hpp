// The thin seam under the V4L2 output sink: open/ioctl/mmap/poll on one device node.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>

namespace io {

// Every call returns 0 (or a count) on success and -errno on failure, like the system calls it
// stands for; the system implementation forwards to them, a simulated one drives unit tests.
class V4l2Device {
  public:
    virtual ~V4l2Device() = default;
    virtual int open(const std::string& path) = 0;            // read/write, non-blocking
    virtual int ioctl(unsigned long request, void* arg) = 0;  // retried on EINTR
    // Maps `length` bytes at `offset`; nullptr with *errorOut = -errno on failure.
    virtual void* map(std::size_t length, std::int64_t offset, int* errorOut) = 0;
    virtual int unmap(void* address, std::size_t length) = 0;
    // Waits up to `timeoutMs` for a buffer to dequeue: 1 ready, 0 timed out, -errno.
    virtual int waitWritable(int timeoutMs) = 0;
    virtual void close() = 0;
};

// The real device node (open(2), ioctl(2), mmap(2), poll(2)).
std::unique_ptr<V4l2Device> makeSystemV4l2Device();

}  // namespace io
