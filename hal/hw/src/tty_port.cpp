#include "hwr/hal/hw/tty_port.hpp"

#include <cerrno>
#include <cstring>
#include <memory>

#include <fcntl.h>
#include <poll.h>
#include <termios.h>
#include <unistd.h>

namespace hwr::hal::hw {
namespace {

bool baud_constant(int baud, speed_t* out) {
  switch (baud) {
    case 9600:
      *out = B9600;
      return true;
    case 19200:
      *out = B19200;
      return true;
    case 38400:
      *out = B38400;
      return true;
    case 57600:
      *out = B57600;
      return true;
    case 115200:
      *out = B115200;
      return true;
    case 230400:
      *out = B230400;
      return true;
    case 460800:
      *out = B460800;
      return true;
    case 921600:
      *out = B921600;
      return true;
    default:
      return false;
  }
}

// errno of a failed open/read/write as a Status a person can act on.
core::Status errno_status(const std::string& path, const char* what, int err) {
  const std::string detail = path + ": " + what + ": " + std::strerror(err);
  switch (err) {
    case ENOENT:
      return core::NotFound(detail + " (is the device plugged in? toolchain/deploy/99-hwr.rules names it)");
    case EACCES:
    case EPERM:
      return core::Status(core::ErrorCode::kIoError,
                          detail + " (add the user to the dialout group: toolchain/deploy/99-hwr.rules)");
    case EIO:
    case ENXIO:
    case ENODEV:
      return core::Unavailable(detail + " (unplugged?)");
    case ENOTTY:
      return core::InvalidArgument(detail + " (not a serial device)");
    default:
      return core::Status(core::ErrorCode::kIoError, detail);
  }
}

}  // namespace

core::Expected<std::unique_ptr<TtyPort>> TtyPort::open(const std::string& path, int baud) {
  speed_t speed;
  if (!baud_constant(baud, &speed)) {
    return core::InvalidArgument(path + ": unsupported baud rate " + std::to_string(baud) +
                                 " (9600, 19200, 38400, 57600, 115200, 230400, 460800, 921600)");
  }
  std::unique_ptr<TtyPort> port(new TtyPort(path, baud));
  if (core::Status st = port->open_and_configure(); !st.ok()) return st;
  return port;
}

TtyPort::~TtyPort() { close_fd(); }

void TtyPort::close_fd() {
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
}

core::Status TtyPort::open_and_configure() {
  close_fd();
  const int fd = ::open(path_.c_str(), O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) return errno_status(path_, "open", errno);
  fd_ = fd;
  termios tio{};
  if (::tcgetattr(fd_, &tio) != 0) {
    const int err = errno;
    close_fd();
    return errno_status(path_, "tcgetattr", err);
  }
  // Raw bytes: no line discipline, no echo, no CR/LF translation, no software flow control;
  // 8 data bits, no parity, 1 stop bit, no RTS/CTS, modem lines ignored (CLOCAL), receiver on.
  ::cfmakeraw(&tio);
  tio.c_cflag &= ~static_cast<tcflag_t>(PARENB | CSTOPB | CSIZE | CRTSCTS);
  tio.c_cflag |= CS8 | CLOCAL | CREAD;
  tio.c_cc[VMIN] = 0;  // reads return what is there; poll() does the waiting
  tio.c_cc[VTIME] = 0;
  speed_t speed = B0;
  baud_constant(baud_, &speed);
  ::cfsetispeed(&tio, speed);
  ::cfsetospeed(&tio, speed);
  if (::tcsetattr(fd_, TCSANOW, &tio) != 0) {
    const int err = errno;
    close_fd();
    return errno_status(path_, "tcsetattr", err);
  }
  ::tcflush(fd_, TCIOFLUSH);  // bytes queued before we configured the port are of unknown framing
  return core::Status::Ok();
}

core::Status TtyPort::reopen() { return open_and_configure(); }

core::Expected<size_t> TtyPort::read_some(uint8_t* buf, size_t cap, int timeout_ms) {
  if (fd_ < 0) return core::Unavailable(path_ + ": not open");
  pollfd p{fd_, POLLIN, 0};
  int r;
  do {
    r = ::poll(&p, 1, timeout_ms);
  } while (r < 0 && errno == EINTR);
  if (r < 0) return errno_status(path_, "poll", errno);
  if (r == 0) return size_t{0};
  if ((p.revents & POLLIN) == 0 && (p.revents & (POLLHUP | POLLERR | POLLNVAL)) != 0) {
    return core::Unavailable(path_ + ": the device hung up (unplugged?)");
  }
  ssize_t n;
  do {
    n = ::read(fd_, buf, cap);
  } while (n < 0 && errno == EINTR);
  if (n < 0) {
    if (errno == EAGAIN) return size_t{0};
    return errno_status(path_, "read", errno);
  }
  if (n == 0) return core::Unavailable(path_ + ": end of stream (unplugged?)");  // hung-up tty reads 0
  return static_cast<size_t>(n);
}

core::Status TtyPort::write_all(const uint8_t* bytes, size_t n) {
  if (fd_ < 0) return core::Unavailable(path_ + ": not open");
  size_t done = 0;
  int stalls = 0;
  while (done < n) {
    const ssize_t w = ::write(fd_, bytes + done, n - done);
    if (w > 0) {
      done += static_cast<size_t>(w);
      continue;
    }
    if (w < 0 && errno == EINTR) continue;
    if (w < 0 && errno == EAGAIN && ++stalls < 50) {  // output buffer full: wait up to ~0.5 s
      pollfd p{fd_, POLLOUT, 0};
      ::poll(&p, 1, 10);
      continue;
    }
    return w < 0 ? errno_status(path_, "write", errno) : core::Unavailable(path_ + ": write stalled");
  }
  return core::Status::Ok();
}

}  // namespace hwr::hal::hw
