#include "hwr/hal/hw/posix_io.hpp"

#include <cerrno>

#include <fcntl.h>
#include <sys/ioctl.h>
#include <sys/mman.h>
#include <unistd.h>

namespace hwr::hal::hw {

int PosixIo::open(const char* path, int flags) { return ::open(path, flags | O_CLOEXEC); }

int PosixIo::close(int fd) { return ::close(fd); }

int PosixIo::ioctl(int fd, unsigned long request, void* arg) {
  int r;
  do {
    r = ::ioctl(fd, request, arg);
  } while (r < 0 && errno == EINTR);
  return r;
}

int PosixIo::poll(pollfd* fds, nfds_t nfds, int timeout_ms) {
  int r;
  do {
    r = ::poll(fds, nfds, timeout_ms);
  } while (r < 0 && errno == EINTR);
  return r;
}

void* PosixIo::mmap(void* addr, size_t length, int prot, int flags, int fd, off_t offset) {
  return ::mmap(addr, length, prot, flags, fd, offset);
}

int PosixIo::munmap(void* addr, size_t length) { return ::munmap(addr, length); }

PosixIo& real_posix_io() {
  static PosixIo io;
  return io;
}

}  // namespace hwr::hal::hw
