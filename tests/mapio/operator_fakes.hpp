#pragma once
// Operator-channel messages for tests (every LCM field set) and a minimal robot that answers
// operator commands over an LcmLink, for the console and hwr-ground round-trip tests.

#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>
#include <map>
#include <string>

#include "hwr/mapio/lcm_link.hpp"
#include "hwr/mapio/operator_wire.hpp"

namespace hwr::mapio::test {

inline constexpr int64_t kMs = 1'000'000;

inline hwr_lcm::detection_t make_detection(int64_t id, int64_t t_ns, int8_t state = 0,
                                           const std::string& robot = "hwr-0") {
  hwr_lcm::detection_t d;  // LCM types leave their scalars uninitialized: set every field
  d.t_ns = t_ns;
  d.robot_id = robot;
  d.run_id = 1732477000000000000;
  d.detection_id = id;
  d.segment_id = 2;
  d.keyframe_t_ns = 1732477000100000000;
  d.source = 1;
  d.state = state;
  d.confidence = 0.75f;
  d.box_px[0] = 100;
  d.box_px[1] = 50;
  d.box_px[2] = 64;
  d.box_px[3] = 32;
  d.box_center_world_m[0] = 1.25 + id;
  d.box_center_world_m[1] = -0.5;
  d.box_center_world_m[2] = 0.75;
  d.box_size_m[0] = 0.4;
  d.box_size_m[1] = d.box_size_m[2] = 0.05;
  d.box_q_world_box[0] = 1;
  d.box_q_world_box[1] = d.box_q_world_box[2] = d.box_q_world_box[3] = 0;
  d.num_seam_points = 2;
  d.seam_world_m = {{1.05 + id, -0.5, 0.7}, {1.45 + id, -0.5, 0.7}};
  return d;
}

// A command as a caller builds it: only the fields its kind uses are set; the rest hold garbage
// (LCM leaves them uninitialized), which send() must clear.
inline hwr_lcm::operator_command_t make_command(OperatorCommandKind kind, int64_t detection_id,
                                                const std::string& robot = "hwr-0") {
  hwr_lcm::operator_command_t c;
  std::memset(static_cast<void*>(c.box_px), 0xFF, sizeof c.box_px);  // NaN patterns
  std::memset(static_cast<void*>(c.box_center_world_m), 0xFF, sizeof c.box_center_world_m);
  std::memset(static_cast<void*>(c.box_size_m), 0xFF, sizeof c.box_size_m);
  std::memset(static_cast<void*>(c.box_q_world_box), 0xFF, sizeof c.box_q_world_box);
  c.t_ns = c.command_id = c.keyframe_t_ns = -77;
  c.robot_id = robot;
  c.kind = static_cast<int8_t>(kind);
  c.detection_id = detection_id;
  if (kind == OperatorCommandKind::kMove) {
    const double center[3] = {2.0, -0.4, 0.8}, size[3] = {0.6, 0.07, 0.07}, q[4] = {1, 0, 0, 0};
    std::memcpy(c.box_center_world_m, center, sizeof center);
    std::memcpy(c.box_size_m, size, sizeof size);
    std::memcpy(c.box_q_world_box, q, sizeof q);
  }
  if (kind == OperatorCommandKind::kAdd) {
    c.keyframe_t_ns = 1732477000100000000;
    const float px[4] = {10, 20, 30, 40};
    std::memcpy(c.box_px, px, sizeof px);
    for (double& v : c.box_center_world_m) v = 0;
    for (double& v : c.box_size_m) v = 0;
    c.box_q_world_box[0] = 1;
    c.box_q_world_box[1] = c.box_q_world_box[2] = c.box_q_world_box[3] = 0;
  }
  return c;
}

inline hwr_lcm::command_ack_t make_ack(int64_t command_id, bool accepted, int64_t detection_id,
                                       const std::string& reason = "", const std::string& robot = "hwr-0") {
  hwr_lcm::command_ack_t a;
  a.t_ns = 1732477009000000000;
  a.robot_id = robot;
  a.command_id = command_id;
  a.accepted = accepted ? 1 : 0;
  a.reason = reason;
  a.detection_id = detection_id;
  return a;
}

// A minimal robot for operator round trips: a detection list that applies each command_id once, acks every
// command (duplicates again) and republishes what changed. The real one lives in hwr-robot.
// Handlers run inside the link's handle()/drain() on the calling thread.
class FakeRobot {
 public:
  explicit FakeRobot(LcmLink* link) : link_(link) {
    link_->subscribe(kChannelOperatorCommand, [this](const uint8_t* d, size_t n) { on_command(d, n); });
  }
  // The robot's ledger; a restarted robot is a new FakeRobot given the old one's (its store).
  struct Ledger {
    std::map<int64_t, hwr_lcm::detection_t> detections;
    std::map<int64_t, hwr_lcm::command_ack_t> applied;  // by command_id: applied once, acked again
    int64_t clock = 1000;                               // t_ns of the next change
  };
  Ledger ledger;
  std::map<int64_t, hwr_lcm::detection_t>& detections = ledger.detections;
  int commands_received = 0;
  bool drop_acks = false;  // applies commands but loses every ack
  bool offline = false;    // ignores commands altogether (a robot not yet started)

  void publish_all() {
    for (auto& [id, d] : detections) ASSERT_TRUE(link_->publish(kChannelDetection, d).ok());
  }

 private:
  void on_command(const uint8_t* data, size_t size) {
    if (offline) return;
    hwr_lcm::operator_command_t c;
    ASSERT_TRUE(decode_operator_command(data, size, &c).ok());
    ++commands_received;
    hwr_lcm::command_ack_t ack = make_ack(c.command_id, true, c.detection_id);
    auto done = ledger.applied.find(c.command_id);
    if (done == ledger.applied.end()) {
      hwr_lcm::detection_t* changed = nullptr;
      if (c.kind == static_cast<int8_t>(OperatorCommandKind::kAdd)) {
        const int64_t id = detections.empty() ? 0 : detections.rbegin()->first + 1;
        hwr_lcm::detection_t d = make_detection(id, 0);
        d.source = 2;
        d.state = 1;
        d.keyframe_t_ns = c.keyframe_t_ns;
        std::copy(c.box_px, c.box_px + 4, d.box_px);
        changed = &(detections[id] = d);
      } else if (auto it = detections.find(c.detection_id); it != detections.end()) {
        changed = &it->second;
        if (c.kind == static_cast<int8_t>(OperatorCommandKind::kReject)) changed->state = 2;
        if (c.kind == static_cast<int8_t>(OperatorCommandKind::kConfirm)) changed->state = 1;
      }
      if (changed == nullptr) {
        ack.accepted = 0;
        ack.reason = "no detection " + std::to_string(c.detection_id);
      } else {
        changed->t_ns = ++ledger.clock;
        ack.detection_id = changed->detection_id;
        ASSERT_TRUE(link_->publish(kChannelDetection, *changed).ok());
      }
      done = ledger.applied.emplace(c.command_id, ack).first;
    }
    if (!drop_acks) {
      ASSERT_TRUE(link_->publish(kChannelOperatorAck, done->second).ok());
    }
  }

  LcmLink* link_;
};

}  // namespace hwr::mapio::test
