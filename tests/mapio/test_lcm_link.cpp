// LcmLink (mapio/lcm_link.hpp): raw publish/subscribe over memq:// in-process and over UDP
// multicast inside a private network namespace, including a 300 KB message (LCM fragments it;
// recv_buf_size in the URL keeps the fragments from being dropped), file:// logs written and
// replayed, and a clear error for a bad URL.

#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdio>
#include <numeric>
#include <vector>

#include "hwr/mapio/lcm_link.hpp"
#include "hwr_lcm/pose_t.hpp"
#include "private_netns.hpp"

namespace hwr::mapio {
namespace {

void round_trip(const std::string& url, size_t big_bytes) {
  auto link = LcmLink::open(url);
  ASSERT_TRUE(link.ok()) << link.status().message();
  std::vector<std::vector<uint8_t>> got;
  link->subscribe("HWR_TEST", [&](const uint8_t* d, size_t n) { got.emplace_back(d, d + n); });
  hwr_lcm::pose_t pose;
  pose.t_ns = 123456789;
  pose.robot_id = "r1";
  pose.run_id = 7;
  for (int i = 0; i < 12; ++i) pose.T_world_cam[i] = i * 0.5;
  int64_t received_t = 0;
  link->subscribe(kChannelPose, [&](const uint8_t* d, size_t n) {
    hwr_lcm::pose_t p;
    ASSERT_EQ(p.decode(d, 0, static_cast<int>(n)), static_cast<int>(n));
    received_t = p.t_ns;
    EXPECT_EQ(p.robot_id, "r1");
    EXPECT_EQ(p.T_world_cam[11], 5.5);
  });
  std::vector<uint8_t> big(big_bytes);
  std::iota(big.begin(), big.end(), uint8_t{0});
  ASSERT_TRUE(link->publish(kChannelPose, pose).ok());
  ASSERT_TRUE(link->publish_bytes("HWR_TEST", big.data(), big.size()).ok());
  for (int i = 0; i < 100 && (got.empty() || received_t == 0); ++i) ASSERT_TRUE(link->handle(50).ok());
  EXPECT_EQ(received_t, 123456789);
  ASSERT_EQ(got.size(), 1u);
  EXPECT_EQ(got[0], big);
}

TEST(LcmLink, GivenMemqThenMessagesRoundTrip) { round_trip("memq://", 300'000); }

TEST(LcmLink, GivenUdpMulticastInPrivateNamespaceThenLargeMessagesRoundTrip) {
  if (!test::in_private_netns()) {
    HWR_RUN_IN_PRIVATE_NETNS();
    return;
  }
  ASSERT_TRUE(test::setup_private_loopback());
  round_trip("udpm://239.255.76.67:7667?ttl=0&recv_buf_size=8388608", 300'000);
}

TEST(LcmLink, GivenBadUrlThenClearError) {
  auto link = LcmLink::open("nosuchprovider://x");
  ASSERT_FALSE(link.ok());
  EXPECT_NE(link.status().message().find("cannot open"), std::string::npos);
}

}  // namespace
}  // namespace hwr::mapio

namespace hwr::mapio {
namespace {

// file:// writes an LCM log that a second LcmLink replays (how a recorded link is inspected later).
TEST(LcmLink, GivenAFileLogThenItReplaysTheMessagesInOrder) {
  const std::string path = ::testing::TempDir() + "hwr_lcm_link_" + std::to_string(::getpid()) + ".lcmlog";
  {
    auto writer = LcmLink::open("file://" + path + "?mode=w");
    ASSERT_TRUE(writer.ok()) << writer.status().message();
    for (int i = 0; i < 5; ++i) {
      hwr_lcm::pose_t pose;
      pose.t_ns = 1000 + i;
      pose.robot_id = "r";
      pose.run_id = 1;
      for (double& v : pose.T_world_cam) v = 0;
      pose.tracking = 1;
      pose.localized = 0;
      ASSERT_TRUE(writer->publish(kChannelPose, pose).ok());
    }
  }
  auto reader = LcmLink::open("file://" + path + "?mode=r&speed=0");
  ASSERT_TRUE(reader.ok()) << reader.status().message();
  std::vector<int64_t> t;
  reader->subscribe(kChannelPose, [&](const uint8_t* d, size_t n) {
    hwr_lcm::pose_t p;
    ASSERT_EQ(p.decode(d, 0, static_cast<int>(n)), static_cast<int>(n));
    t.push_back(p.t_ns);
  });
  for (int i = 0; i < 50 && t.size() < 5; ++i) {
    auto r = reader->handle(100);
    if (!r.ok()) break;  // end of the log
  }
  EXPECT_EQ(t, (std::vector<int64_t>{1000, 1001, 1002, 1003, 1004}));
  std::remove(path.c_str());
}

}  // namespace
}  // namespace hwr::mapio
