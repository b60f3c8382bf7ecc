// TtyPort on a real pseudo-terminal: the termios settings it applies read back from the tty, bytes
// pass both ways, a hung-up peer is Unavailable and reopen() recovers, errors name the device.
#include "hwr/hal/hw/tty_port.hpp"

#include <gtest/gtest.h>

#include <cstdlib>
#include <cstring>
#include <memory>
#include <string>

#include <fcntl.h>
#include <termios.h>
#include <unistd.h>

namespace hwr::hal::hw {
namespace {

struct Pty {
  int master = -1;
  std::string slave;
  Pty() {
    master = ::posix_openpt(O_RDWR | O_NOCTTY);
    if (master < 0 || ::grantpt(master) != 0 || ::unlockpt(master) != 0) return;
    slave = ::ptsname(master);
  }
  ~Pty() {
    if (master >= 0) ::close(master);
  }
};

TEST(TtyPort, GivenAPtyThenItIsRaw8N1AtTheBaudAndBytesArrive) {
  Pty pty;
  ASSERT_FALSE(pty.slave.empty());
  auto port = TtyPort::open(pty.slave, 921600);
  ASSERT_TRUE(port.ok()) << port.status().message();
  termios tio{};
  ASSERT_EQ(::tcgetattr((*port)->fd(), &tio), 0);
  EXPECT_EQ(tio.c_cflag & CSIZE, static_cast<tcflag_t>(CS8));
  EXPECT_EQ(tio.c_cflag & (PARENB | CSTOPB | CRTSCTS), 0u);
  EXPECT_NE(tio.c_cflag & CLOCAL, 0u);
  EXPECT_EQ(tio.c_lflag & (ICANON | ECHO | ISIG), 0u);
  EXPECT_EQ(tio.c_iflag & (ICRNL | IXON), 0u);
  EXPECT_EQ(tio.c_oflag & OPOST, 0u);
  // qemu-user's termios translation (the agx preset's tests) does not carry the rate back: checked
  // only where the test runs natively.
  if (std::string(HWR_TEST_EMULATOR).empty()) {
    EXPECT_EQ(::cfgetispeed(&tio), static_cast<speed_t>(B921600));
  }

  const uint8_t frame[] = {0xAA, 0x55, 0x0D, 0x0A, 0x11, 0x13, 0x00};  // CR LF XON XOFF pass untouched
  ASSERT_EQ(::write(pty.master, frame, sizeof frame), static_cast<ssize_t>(sizeof frame));
  uint8_t buf[64];
  size_t got = 0;
  for (int i = 0; i < 20 && got < sizeof frame; ++i) {
    auto n = (*port)->read_some(buf + got, sizeof buf - got, 100);
    ASSERT_TRUE(n.ok()) << n.status().message();
    got += n.value();
  }
  ASSERT_EQ(got, sizeof frame);
  EXPECT_EQ(0, std::memcmp(buf, frame, sizeof frame));

  const uint8_t cfg[] = {0xB5, 0x62, 0x06, 0x08};
  ASSERT_TRUE((*port)->write_all(cfg, sizeof cfg).ok());
  uint8_t back[8];
  ASSERT_EQ(::read(pty.master, back, sizeof back), static_cast<ssize_t>(sizeof cfg));
  EXPECT_EQ(0, std::memcmp(back, cfg, sizeof cfg));
}

TEST(TtyPort, GivenNothingSentThenAReadTimesOutWithZeroBytes) {
  Pty pty;
  auto port = TtyPort::open(pty.slave, 115200);
  ASSERT_TRUE(port.ok());
  uint8_t buf[8];
  auto n = (*port)->read_some(buf, sizeof buf, 10);
  ASSERT_TRUE(n.ok());
  EXPECT_EQ(n.value(), 0u);
}

TEST(TtyPort, GivenThePeerGoneThenUnavailableAndReopenSaysWhy) {
  auto pty = std::make_unique<Pty>();
  const std::string path = pty->slave;
  auto port = TtyPort::open(path, 115200);
  ASSERT_TRUE(port.ok());
  pty.reset();  // the master closes: the slave hangs up, as an unplugged USB adapter does
  uint8_t buf[8];
  auto n = (*port)->read_some(buf, sizeof buf, 100);
  ASSERT_FALSE(n.ok());
  EXPECT_EQ(n.status().code(), core::ErrorCode::kUnavailable) << n.status().message();
  EXPECT_NE(n.status().message().find(path), std::string::npos);
  core::Status st = (*port)->reopen();  // the pty is gone for good
  EXPECT_FALSE(st.ok());
}

TEST(TtyPort, GivenAMissingDeviceThenNotFoundNamesIt) {
  auto port = TtyPort::open("/dev/hwr-no-such-a9", 921600);
  ASSERT_FALSE(port.ok());
  EXPECT_EQ(port.status().code(), core::ErrorCode::kNotFound);
  EXPECT_NE(port.status().message().find("/dev/hwr-no-such-a9"), std::string::npos);
  EXPECT_NE(port.status().message().find("plugged in"), std::string::npos);
}

TEST(TtyPort, GivenAnUnsupportedBaudOrAFileThenAClearError) {
  auto bad_baud = TtyPort::open("/dev/null", 12345);
  ASSERT_FALSE(bad_baud.ok());
  EXPECT_NE(bad_baud.status().message().find("unsupported baud rate 12345"), std::string::npos);
  auto not_tty = TtyPort::open("/dev/null", 9600);
  ASSERT_FALSE(not_tty.ok());
  EXPECT_NE(not_tty.status().message().find("not a serial device"), std::string::npos)
      << not_tty.status().message();
}

}  // namespace
}  // namespace hwr::hal::hw
