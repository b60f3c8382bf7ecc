// A9Reader: frames from a scripted port become ImuSamples in the ring, stamped on the host clock
// with the device's spacing; noise is skipped; an unplugged port is retried with backoff and the
// stream starts over when it comes back.
#include "hwr/hal/hw/a9_reader.hpp"

#include <gtest/gtest.h>

#include <cstring>
#include <memory>
#include <vector>

#include "a9_frames.hpp"
#include "fake_byte_stream.hpp"

namespace hwr::hal::hw {
namespace {

using Bytes = std::vector<uint8_t>;

Bytes imu_frame(uint32_t t_us, float accel_z_g) {
  return test::make_a9_imu_frame(t_us, {0.01f, 0.02f, 0.03f}, {0.0f, 0.0f, accel_z_g}, {0.3f, 0.0f, 0.4f});
}

struct Rig {
  core::SpscRing<ImuSample> ring{64};
  test::FakeByteStream* port = nullptr;
  std::unique_ptr<A9Reader> reader;
  Rig() {
    auto p = std::make_unique<test::FakeByteStream>("/dev/hwr-a9");
    port = p.get();
    reader = std::make_unique<A9Reader>(std::move(p), &ring);
  }
  std::vector<ImuSample> drain() {
    std::vector<ImuSample> out;
    ImuSample s;
    while (ring.try_pop(s)) out.push_back(s);
    return out;
  }
};

TEST(A9Reader, GivenFramesWithNoiseThenSamplesKeepTheDeviceSpacingOnTheHostClock) {
  Rig rig;
  const int64_t host0 = 50'000'000'000;
  // Frames at 150 Hz (6667 µs apart); each read returns noise + one frame, 2 ms after sampling.
  for (int i = 0; i < 10; ++i) {
    Bytes chunk = {0x00, 0xAA, 0x13};  // noise, including a lone sync byte
    const Bytes f = imu_frame(1'000'000 + static_cast<uint32_t>(i) * 6667, -1.0f);
    chunk.insert(chunk.end(), f.begin(), f.end());
    rig.port->reads.push_back({chunk, {}});
    ASSERT_TRUE(rig.reader->step(host0 + i * 6'667'000 + 2'000'000).ok());
  }
  const auto s = rig.drain();
  ASSERT_EQ(s.size(), 10u);
  for (size_t i = 1; i < s.size(); ++i) EXPECT_EQ(s[i].t_ns - s[i - 1].t_ns, 6'667'000);
  EXPECT_EQ(s[0].t_ns, host0 + 2'000'000);          // constant latency: first receipt time
  EXPECT_NEAR(s[0].accel_mps2.z(), 9.80665, 1e-5);  // −1 g on the A9's z-down axis → +g up
  EXPECT_EQ(rig.reader->counters().samples, 10u);
  EXPECT_EQ(rig.reader->counters().bytes_discarded, 30u);
}

TEST(A9Reader, GivenAFrameSplitAcrossReadsThenItIsDecodedOnce) {
  Rig rig;
  const Bytes f = imu_frame(42, -1.0f);
  rig.port->reads.push_back({Bytes(f.begin(), f.begin() + 20), {}});
  rig.port->reads.push_back({Bytes(f.begin() + 20, f.end()), {}});
  ASSERT_TRUE(rig.reader->step(1'000'000).ok());
  EXPECT_TRUE(rig.drain().empty());
  ASSERT_TRUE(rig.reader->step(2'000'000).ok());
  EXPECT_EQ(rig.drain().size(), 1u);
}

TEST(A9Reader, GivenACorruptFrameThenItIsCountedAndTheNextOneDecoded) {
  Rig rig;
  Bytes bad = imu_frame(100, -1.0f);
  bad[20] ^= 0x10;
  Bytes chunk = bad;
  const Bytes good = imu_frame(6767, -1.0f);
  chunk.insert(chunk.end(), good.begin(), good.end());
  rig.port->reads.push_back({chunk, {}});
  ASSERT_TRUE(rig.reader->step(1'000'000).ok());
  EXPECT_EQ(rig.drain().size(), 1u);
  EXPECT_EQ(rig.reader->counters().crc_errors, 1u);
}

TEST(A9Reader, GivenTheDeviceUnpluggedThenItReconnectsWithBackoffAndStartsOver) {
  Rig rig;
  rig.port->reads.push_back({imu_frame(1000, -1.0f), {}});
  rig.port->reads.push_back({{}, core::Unavailable("/dev/hwr-a9: unplugged")});
  ASSERT_TRUE(rig.reader->step(1'000'000'000).ok());
  ASSERT_TRUE(rig.reader->step(1'010'000'000).ok());  // the read fails: disconnected
  EXPECT_FALSE(rig.reader->connected());
  EXPECT_EQ(rig.reader->counters().disconnects, 1u);
  // Still unplugged: the first reopen (after 0.1 s) fails, the next is 0.2 s later.
  rig.port->reopens.push_back(core::NotFound("no such device /dev/hwr-a9"));
  ASSERT_TRUE(rig.reader->step(1'050'000'000).ok());  // backoff not due: no reopen
  EXPECT_EQ(rig.port->reopen_calls, 0);
  ASSERT_TRUE(rig.reader->step(1'111'000'000).ok());
  EXPECT_EQ(rig.port->reopen_calls, 1);
  ASSERT_TRUE(rig.reader->step(1'250'000'000).ok());  // 0.2 s after the failed reopen: not yet
  EXPECT_EQ(rig.port->reopen_calls, 1);
  // Replugged: the A9 restarted its clock at 0.
  rig.port->reads.push_back({imu_frame(5, -1.0f), {}});
  ASSERT_TRUE(rig.reader->step(1'320'000'000).ok());
  EXPECT_EQ(rig.port->reopen_calls, 2);
  EXPECT_TRUE(rig.reader->connected());
  EXPECT_EQ(rig.reader->counters().reconnects, 1u);
  const auto s = rig.drain();
  ASSERT_EQ(s.size(), 2u);
  EXPECT_EQ(s[1].t_ns, 1'320'000'000);  // a fresh clock map: stamped at its receipt, not before
}

TEST(A9Reader, GivenAnErrorAReconnectCannotFixThenStepReturnsIt) {
  Rig rig;
  rig.port->reads.push_back({{}, core::InvalidArgument("/dev/hwr-a9: not a tty")});
  EXPECT_FALSE(rig.reader->step(0).ok());
}

}  // namespace
}  // namespace hwr::hal::hw
