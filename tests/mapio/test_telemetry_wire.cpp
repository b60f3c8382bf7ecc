// The robot's telemetry as the ground station decodes it (mapio/telemetry_wire.hpp): pose_t, status_t
// and keyframe_image_t round trip; every truncation, hostile count and length, leftover byte, wrong
// type, and every invalid field is refused with an error naming it, before anything is allocated.

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "hwr/mapio/telemetry_wire.hpp"

namespace hwr::mapio {
namespace {

hwr_lcm::pose_t make_pose() {
  hwr_lcm::pose_t p;
  p.t_ns = 1'700'000'000'000'000'000;
  p.robot_id = "hwr-0";
  p.run_id = 1'732'477'000'000'000'000;
  const double T[12] = {0, -1, 0, 1.5, 1, 0, 0, -2.25, 0, 0, 1, 0.75};  // 90 deg about z
  std::copy(T, T + 12, p.T_world_cam);
  p.tracking = 1;
  p.localized = 0;
  return p;
}

hwr_lcm::status_t make_status() {
  hwr_lcm::status_t s;
  s.t_ns = 5;
  s.robot_id = "hwr-0";
  s.run_id = 7;
  s.num_tasks = 2;
  s.task_name = {"camera", "mapping"};
  s.task_runs = {300, 100};
  s.task_overruns = {4, 1};
  s.task_slips = {0, 2};
  s.num_counters = 1;
  s.counter_name = {"link.resends"};
  s.counter_value = {3};
  return s;
}

hwr_lcm::keyframe_image_t make_image() {
  hwr_lcm::keyframe_image_t m;
  m.t_ns = 9;
  m.robot_id = "hwr-0";
  m.run_id = 7;
  m.keyframe_t_ns = 1'700'000'000'100'000'000;
  m.width = 1280;
  m.height = 720;
  m.jpeg_width = 640;
  m.jpeg_height = 360;
  m.jpeg = {0xFF, 0xD8, 0xFF, 0xE0, 0x00, 0x10, 0xFF, 0xD9};
  m.size = static_cast<int32_t>(m.jpeg.size());
  return m;
}

template <class Msg>
std::vector<uint8_t> lcm_encode(const Msg& m) {
  std::vector<uint8_t> b(static_cast<size_t>(m.getEncodedSize()));
  m.encode(b.data(), 0, static_cast<int>(b.size()));
  return b;
}

core::Status decode(const std::vector<uint8_t>& b, hwr_lcm::pose_t* out) {
  return decode_pose(b.data(), b.size(), out);
}
core::Status decode(const std::vector<uint8_t>& b, hwr_lcm::status_t* out) {
  return decode_status(b.data(), b.size(), out);
}
core::Status decode(const std::vector<uint8_t>& b, hwr_lcm::keyframe_image_t* out) {
  return decode_keyframe_image(b.data(), b.size(), out);
}

bool mentions(const core::Status& st, const std::string& what) {
  return st.message().find(what) != std::string::npos;
}

void put_be32(std::vector<uint8_t>* b, size_t at, int32_t v) {
  const auto u = static_cast<uint32_t>(v);
  for (int i = 0; i < 4; ++i) (*b)[at + static_cast<size_t>(i)] = static_cast<uint8_t>(u >> (24 - 8 * i));
}

// Offsets: fingerprint 8, t_ns 8, robot_id "hwr-0" (4 + 6), run_id 8.
constexpr size_t kRobotIdLengthAt = 16;
constexpr size_t kAfterRunId = 16 + 10 + 8;  // status_t: num_tasks; keyframe_image_t: keyframe_t_ns

template <class Msg>
void expect_every_prefix_rejected(const std::vector<uint8_t>& full) {
  Msg out;
  for (size_t n = 0; n < full.size(); ++n) {
    const core::Status st =
        decode(std::vector<uint8_t>(full.begin(), full.begin() + static_cast<std::ptrdiff_t>(n)), &out);
    EXPECT_FALSE(st.ok()) << "prefix " << n;
  }
  EXPECT_TRUE(decode(full, &out).ok());
}

TEST(TelemetryWire, GivenEncodedMessagesWhenDecodedThenEveryFieldMatches) {
  hwr_lcm::pose_t pose;
  ASSERT_TRUE(decode(lcm_encode(make_pose()), &pose).ok());
  EXPECT_EQ(pose.robot_id, "hwr-0");
  EXPECT_EQ(pose.run_id, make_pose().run_id);
  EXPECT_EQ(pose.T_world_cam[3], 1.5);
  EXPECT_EQ(pose.T_world_cam[11], 0.75);
  hwr_lcm::status_t status;
  ASSERT_TRUE(decode(lcm_encode(make_status()), &status).ok());
  EXPECT_EQ(status.task_name[1], "mapping");
  EXPECT_EQ(status.task_overruns[0], 4);
  EXPECT_EQ(status.counter_value[0], 3);
  hwr_lcm::keyframe_image_t image;
  ASSERT_TRUE(decode(lcm_encode(make_image()), &image).ok());
  EXPECT_EQ(image.keyframe_t_ns, make_image().keyframe_t_ns);
  EXPECT_EQ(image.jpeg, make_image().jpeg);
  std::vector<uint8_t> out;
  EXPECT_TRUE(encode_status(make_status(), &out).ok());
  EXPECT_EQ(out, lcm_encode(make_status()));
}

TEST(TelemetryWire, GivenEveryTruncationThenRejected) {
  expect_every_prefix_rejected<hwr_lcm::pose_t>(lcm_encode(make_pose()));
  expect_every_prefix_rejected<hwr_lcm::status_t>(lcm_encode(make_status()));
  expect_every_prefix_rejected<hwr_lcm::keyframe_image_t>(lcm_encode(make_image()));
}

TEST(TelemetryWire, GivenHostileCountsAndLengthsThenRejectedNamingTheFieldBeforeAllocating) {
  hwr_lcm::status_t status;
  for (const int32_t n : {std::numeric_limits<int32_t>::max(), -1, 65}) {
    auto b = lcm_encode(make_status());
    put_be32(&b, kAfterRunId, n);
    const core::Status st = decode(b, &status);
    EXPECT_FALSE(st.ok()) << n;
    EXPECT_TRUE(mentions(st, "num_tasks")) << st.message();
    EXPECT_LE(status.task_name.capacity(), 64u);
  }
  hwr_lcm::keyframe_image_t image;
  const size_t size_at = kAfterRunId + 8 + 16;
  for (const int32_t n : {std::numeric_limits<int32_t>::max(), -1, 3 << 21}) {
    auto b = lcm_encode(make_image());
    put_be32(&b, size_at, n);
    const core::Status st = decode(b, &image);
    EXPECT_FALSE(st.ok()) << n;
    EXPECT_TRUE(mentions(st, "size") || mentions(st, "jpeg")) << st.message();
    EXPECT_LE(image.jpeg.capacity(), 4096u);
  }
  hwr_lcm::pose_t pose;
  for (const int32_t len : {0, -5, 66, std::numeric_limits<int32_t>::max()}) {
    auto b = lcm_encode(make_pose());
    put_be32(&b, kRobotIdLengthAt, len);
    const core::Status st = decode(b, &pose);
    EXPECT_FALSE(st.ok()) << len;
    EXPECT_TRUE(mentions(st, "robot_id")) << st.message();
  }
}

TEST(TelemetryWire, GivenLeftoverBytesOrAnotherTypeThenParseError) {
  auto b = lcm_encode(make_pose());
  b.push_back(0);
  hwr_lcm::pose_t pose;
  EXPECT_EQ(decode(b, &pose).code(), core::ErrorCode::kParseError);
  hwr_lcm::status_t status;
  const core::Status st = decode(lcm_encode(make_pose()), &status);
  EXPECT_EQ(st.code(), core::ErrorCode::kParseError);
  EXPECT_TRUE(mentions(st, "not a status_t")) << st.message();
}

TEST(TelemetryWire, GivenInvalidFieldsThenVerifyNamesThem) {
  hwr_lcm::pose_t p = make_pose();
  p.T_world_cam[5] = std::nan("");
  EXPECT_TRUE(mentions(verify_pose(p), "T_world_cam[5] is not finite"));
  p = make_pose();
  p.T_world_cam[0] = 2;  // not a rotation
  EXPECT_TRUE(mentions(verify_pose(p), "orthonormal"));
  p = make_pose();
  p.tracking = 2;
  EXPECT_EQ(verify_pose(p).code(), core::ErrorCode::kOutOfRange);
  p = make_pose();
  p.robot_id = "../x";
  EXPECT_FALSE(verify_pose(p).ok());
  p = make_pose();
  p.run_id = -1;
  EXPECT_TRUE(mentions(verify_pose(p), "run_id"));

  hwr_lcm::status_t s = make_status();
  s.task_overruns[1] = -2;
  EXPECT_TRUE(mentions(verify_status(s), "mapping"));
  s = make_status();
  s.num_counters = 2;  // disagrees with the arrays: encode must refuse, not read past them
  std::vector<uint8_t> out;
  EXPECT_TRUE(mentions(encode_status(s, &out), "num_counters"));
  s = make_status();
  s.task_name[0] = std::string(65, 'a');
  EXPECT_FALSE(verify_status(s).ok());

  hwr_lcm::keyframe_image_t m = make_image();
  m.jpeg[0] = 0x89;  // a PNG, say
  EXPECT_TRUE(mentions(verify_keyframe_image(m), "not a JPEG"));
  m = make_image();
  m.width = 0;
  EXPECT_TRUE(mentions(verify_keyframe_image(m), "width"));
  m = make_image();
  m.size = 3;
  EXPECT_TRUE(mentions(verify_keyframe_image(m), "size"));
  m = make_image();
  m.keyframe_t_ns = -1;
  EXPECT_TRUE(mentions(verify_keyframe_image(m), "keyframe_t_ns"));
}

}  // namespace
}  // namespace hwr::mapio
