#pragma once
// The few system calls a device driver makes (open, close, ioctl, poll, mmap, munmap) behind one
// virtual seam, so that the driver's ioctl logic runs in the tests against a fake kernel
// (tests/hal_hw/test_v4l2_capture.cpp emulates uvcvideo). POSIX conventions throughout: failure is
// -1 (MAP_FAILED for mmap) with errno set. The default implementation is the real syscalls; ioctl and
// poll retry EINTR, so no caller has to.

#include <poll.h>
#include <sys/types.h>

#include <cstddef>

namespace hwr::hal::hw {

class PosixIo {
 public:
  virtual ~PosixIo() = default;

  virtual int open(const char* path, int flags);
  virtual int close(int fd);
  virtual int ioctl(int fd, unsigned long request, void* arg);
  // A retry after EINTR waits the full timeout_ms again (a signal mid-wait can lengthen one wait).
  virtual int poll(pollfd* fds, nfds_t nfds, int timeout_ms);
  virtual void* mmap(void* addr, size_t length, int prot, int flags, int fd, off_t offset);
  virtual int munmap(void* addr, size_t length);
};

// The process-wide instance that makes the real syscalls.
PosixIo& real_posix_io();

}  // namespace hwr::hal::hw
