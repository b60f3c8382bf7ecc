// GnssReader: configures the receiver (CFG-RATE, then CFG-MSG NAV-PVT, each after the previous
// ACK), turns NAV-PVT into fixes, falls back to GGA only while NAV-PVT is silent, says which message
// a NAK refused, gives up after unanswered tries, and configures again after a reconnect.
#include "hwr/hal/hw/gnss_reader.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "fake_byte_stream.hpp"

namespace hwr::hal::hw {
namespace {

using Bytes = std::vector<uint8_t>;

Bytes ack(bool ok, uint8_t cls, uint8_t id) {
  const uint8_t p[2] = {cls, id};
  return make_ubx_frame(0x05, ok ? 0x01 : 0x00, p, 2);
}

Bytes nav_pvt(double lat_deg, double lon_deg) {
  Bytes p(92, 0);
  auto put = [&](size_t off, int64_t v, int n) {
    for (int i = 0; i < n; ++i) p[off + static_cast<size_t>(i)] = static_cast<uint8_t>(v >> (8 * i));
  };
  p[20] = 3;     // fixType 3D
  p[21] = 0x01;  // gnssFixOK
  p[23] = 9;     // numSV
  put(24, std::llround(lon_deg * 1e7), 4);
  put(28, std::llround(lat_deg * 1e7), 4);
  put(32, 250'000, 4);  // height 250 m
  put(40, 1'500, 4);    // hAcc 1.5 m
  put(44, 2'500, 4);
  return make_ubx_frame(0x01, 0x07, p.data(), p.size());
}

Bytes text(const std::string& s) { return Bytes(s.begin(), s.end()); }
const char* kGga = "$GNGGA,173002.00,6322.46840,N,01020.45757,E,1,05,7.83,167.0,M,40.1,M,,*45\r\n";

// A receiver that acknowledges every CFG message it gets (or NAKs the one named).
void answer_config(test::FakeByteStream* port, int nak_id = -1) {
  port->on_write = [nak_id](const Bytes& w, test::FakeByteStream* p) {
    if (w.size() >= 4 && w[2] == 0x06) p->reads.push_back({ack(w[3] != nak_id, w[2], w[3]), {}});
  };
}

struct Rig {
  core::SpscRing<GnssFix> ring{16};
  test::FakeByteStream* port = nullptr;
  std::unique_ptr<GnssReader> reader;
  explicit Rig(GnssReaderOptions o = {}) {
    auto p = std::make_unique<test::FakeByteStream>("/dev/hwr-gnss");
    port = p.get();
    reader = std::make_unique<GnssReader>(std::move(p), &ring, o);
  }
  std::vector<GnssFix> drain() {
    std::vector<GnssFix> out;
    GnssFix f;
    while (ring.try_pop(f)) out.push_back(f);
    return out;
  }
};

TEST(GnssReader, GivenAReceiverThatAcksThenItIsConfiguredInOrderAndNavPvtBecomesFixes) {
  Rig rig;
  answer_config(rig.port);
  ASSERT_TRUE(rig.reader->step(1'000'000'000).ok());  // sends CFG-RATE, reads its ACK, sends CFG-MSG
  ASSERT_TRUE(rig.reader->step(1'010'000'000).ok());  // reads the CFG-MSG ACK
  ASSERT_EQ(rig.port->writes.size(), 2u);
  // hardware.md's exact bytes for 10 Hz and NAV-PVT on.
  EXPECT_EQ(rig.port->writes[0],
            (Bytes{0xB5, 0x62, 0x06, 0x08, 0x06, 0x00, 0x64, 0x00, 0x01, 0x00, 0x01, 0x00, 0x7A, 0x12}));
  EXPECT_EQ(rig.port->writes[1], (Bytes{0xB5, 0x62, 0x06, 0x01, 0x03, 0x00, 0x01, 0x07, 0x01, 0x13, 0x51}));
  EXPECT_EQ(rig.reader->config_state(), GnssConfigState::kDone);
  EXPECT_EQ(rig.reader->counters().acks, 2u);

  rig.port->reads.push_back({nav_pvt(47.3977419, 8.5455938), {}});
  ASSERT_TRUE(rig.reader->step(1'100'000'000).ok());
  const auto fixes = rig.drain();
  ASSERT_EQ(fixes.size(), 1u);
  EXPECT_EQ(fixes[0].t_ns, 1'100'000'000);
  EXPECT_EQ(fixes[0].fix_type, 3);
  EXPECT_EQ(fixes[0].num_sv, 9);
  EXPECT_NEAR(fixes[0].lat_deg, 47.3977419, 1e-7);
  EXPECT_NEAR(fixes[0].lon_deg, 8.5455938, 1e-7);
  EXPECT_NEAR(fixes[0].height_m, 250.0, 1e-9);
  EXPECT_NEAR(fixes[0].h_acc_m, 1.5, 1e-9);
}

TEST(GnssReader, GivenNavPvtFlowingThenGgaIsIgnoredAndAfterSilenceItIsTheFallback) {
  GnssReaderOptions o;
  o.configure = false;
  Rig rig(o);
  Bytes both = nav_pvt(10.0, 20.0);
  const Bytes g = text(kGga);
  both.insert(both.end(), g.begin(), g.end());
  rig.port->reads.push_back({both, {}});
  ASSERT_TRUE(rig.reader->step(5'000'000'000).ok());
  EXPECT_EQ(rig.drain().size(), 1u);  // the NAV-PVT only
  EXPECT_EQ(rig.reader->counters().gga, 1u);
  // 2.5 s without NAV-PVT: GGA is used.
  rig.port->reads.push_back({g, {}});
  ASSERT_TRUE(rig.reader->step(7'500'000'000).ok());
  const auto fixes = rig.drain();
  ASSERT_EQ(fixes.size(), 1u);
  EXPECT_NEAR(fixes[0].lat_deg, 63.0 + 22.46840 / 60.0, 1e-9);
  EXPECT_EQ(rig.reader->counters().fixes_from_gga, 1u);
  EXPECT_TRUE(rig.port->writes.empty());  // configure: false sends nothing
}

TEST(GnssReader, GivenANakThenTheErrorNamesTheRefusedMessageAndReadingGoesOn) {
  Rig rig;
  answer_config(rig.port, /*nak_id=*/0x08);
  core::Status st = rig.reader->step(0);
  ASSERT_FALSE(st.ok());
  EXPECT_NE(st.message().find("CFG-RATE"), std::string::npos) << st.message();
  EXPECT_NE(st.message().find("ACK-NAK"), std::string::npos);
  EXPECT_EQ(rig.reader->config_state(), GnssConfigState::kFailed);
  rig.port->reads.push_back({text(kGga), {}});
  EXPECT_TRUE(rig.reader->step(10'000'000'000).ok());
  EXPECT_EQ(rig.drain().size(), 1u);
}

TEST(GnssReader, GivenNoAnswerThenItRetriesAndGivesUpWithATimeout) {
  Rig rig;  // nothing answers
  int64_t t = 0;
  core::Status st;
  for (int i = 0; i < 100 && st.ok(); ++i, t += 100'000'000) st = rig.reader->step(t);
  ASSERT_FALSE(st.ok());
  EXPECT_EQ(st.code(), core::ErrorCode::kTimeout);
  EXPECT_EQ(rig.port->writes.size(), 3u);  // max_config_tries CFG-RATE frames
  EXPECT_NE(st.message().find("/dev/hwr-gnss"), std::string::npos);
}

TEST(GnssReader, GivenAReconnectThenTheReceiverIsConfiguredAgain) {
  Rig rig;
  answer_config(rig.port);
  ASSERT_TRUE(rig.reader->step(0).ok());
  ASSERT_TRUE(rig.reader->step(10'000'000).ok());
  ASSERT_EQ(rig.reader->config_state(), GnssConfigState::kDone);
  rig.port->reads.push_back({{}, core::Unavailable("unplugged")});
  ASSERT_TRUE(rig.reader->step(20'000'000).ok());
  EXPECT_FALSE(rig.reader->connected());
  ASSERT_TRUE(rig.reader->step(200'000'000).ok());  // reopen, CFG-RATE again
  ASSERT_TRUE(rig.reader->step(210'000'000).ok());
  EXPECT_EQ(rig.reader->counters().reconnects, 1u);
  EXPECT_EQ(rig.port->writes.size(), 4u);
  EXPECT_EQ(rig.reader->config_state(), GnssConfigState::kDone);
}

}  // namespace
}  // namespace hwr::hal::hw
