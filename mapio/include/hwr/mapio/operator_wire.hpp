#pragma once
// The wire rules of the operator channel (issue #7 item 4): detections streamed to the ground station
// (detection_t on HWR_DETECTION), operator commands back to the robot (operator_command_t on
// HWR_OPERATOR_CMD) and their acknowledgements (command_ack_t on HWR_OPERATOR_ACK). Every received
// message is decoded without letting a length field allocate (LCM 1.3.1's generated decode() resizes
// vectors to whatever a count says) and then validated, so a handler only sees messages it can act on.
//
// Decoding: the message size against max_message_bytes, the type fingerprint, robot_id (and reason)
// as an LCM string within its limit, num_seam_points in 0..max_seam_points, all of it against the
// bytes present, and nothing left over. kParseError / kOutOfRange naming the field and its offset.
//
// Validation (verify_*; decode_* runs it after decoding), in this order:
//   every message  robot_id [A-Za-z0-9_-]{1,max_robot_id_bytes} (it names folders on both ends):
//                  kOutOfRange when empty or too long, kInvalidArgument for another character;
//                  every float and double finite (also the fields a command kind ignores: a NaN
//                  there is an unset LCM scalar): kInvalidArgument.
//   detection_t    detection_id >= 0; source 0..2, state 0..2, confidence in [0, 1], box_px width and
//                  height >= 0, box_size_m >= 0 (kOutOfRange); |box_q_world_box| within 1e-3 of 1
//                  (kInvalidArgument); num_seam_points == seam_world_m.size() in 0..max_seam_points,
//                  each point 3 values (kInvalidArgument / kOutOfRange).
//   operator_command_t
//                  command_id >= 0, kind 0..3 (kOutOfRange);
//                  confirm, reject, move: detection_id >= 0 (kOutOfRange);
//                  move:  box_size_m > 0 on each axis (kOutOfRange), a unit box_q_world_box;
//                  add:   box_px x, y >= 0 and width, height > 0 (kOutOfRange); the world box is
//                         optional: box_size_m all 0 means none (the robot derives it from the
//                         keyframe), otherwise all > 0 with a unit box_q_world_box.
//   command_ack_t  command_id >= 0, accepted 0/1 (kOutOfRange); reason within max_reason_bytes
//                  (checked while decoding).
// Frames and units as in the .lcm files: box_px in pixels of the keyframe image (x, y, width,
// height), box_center_world_m / box_size_m in metres in the world frame (full sizes along the box's
// axes), box_q_world_box the box's orientation in the world frame (w, x, y, z), seam_world_m points
// in metres in the world frame.

#include <cstddef>
#include <cstdint>
#include <vector>

#include "hwr/core/status.hpp"
#include "hwr_lcm/command_ack_t.hpp"
#include "hwr_lcm/detection_t.hpp"
#include "hwr_lcm/operator_command_t.hpp"

namespace hwr::mapio {

// What a receiver accepts. A detection with 64 seam points encodes to ~1.7 kB; the limits leave
// margin and bound what one message can make a receiver allocate.
struct OperatorWireLimits {
  size_t max_message_bytes = 64u << 10;
  size_t max_robot_id_bytes = 64;  // robot_id [A-Za-z0-9_-]{1,64}
  int max_seam_points = 64;        // detection_t.num_seam_points
  size_t max_reason_bytes = 512;   // command_ack_t.reason
};

// detection_t.source / .state and operator_command_t.kind.
enum class DetectionSource : int8_t { kModel = 0, kGeometry = 1, kOperator = 2 };
enum class DetectionState : int8_t { kProposed = 0, kConfirmed = 1, kRejected = 2 };
enum class OperatorCommandKind : int8_t { kConfirm = 0, kReject = 1, kMove = 2, kAdd = 3 };

// |q| may differ from 1 by this much (floats rounded to text and back, a hand-typed quaternion).
inline constexpr double kUnitQuaternionTolerance = 1e-3;

// Bounded LCM decoding (LCM's generated decode() resizes vectors to whatever a count says): every
// length field checked against the bytes present and the limits before anything is allocated;
// wrong fingerprint, leftover bytes, a bad string -> kParseError/kOutOfRange naming the field. Then
// the validation above (verify_*). `out` is overwritten (vectors keep their capacity); on error its
// contents are unspecified.
core::Status decode_detection(const uint8_t* data, size_t size, hwr_lcm::detection_t* out,
                              const OperatorWireLimits& limits = {});
core::Status decode_operator_command(const uint8_t* data, size_t size, hwr_lcm::operator_command_t* out,
                                     const OperatorWireLimits& limits = {});
core::Status decode_command_ack(const uint8_t* data, size_t size, hwr_lcm::command_ack_t* out,
                                const OperatorWireLimits& limits = {});

// The validation alone, for a message about to be sent or read back from disk.
core::Status verify_detection(const hwr_lcm::detection_t& detection, const OperatorWireLimits& limits = {});
core::Status verify_operator_command(const hwr_lcm::operator_command_t& command,
                                     const OperatorWireLimits& limits = {});
core::Status verify_command_ack(const hwr_lcm::command_ack_t& ack, const OperatorWireLimits& limits = {});

// Verifies, then LCM-encodes into `out` (resized to the message; capacity kept). Use these (or
// verify_* before LcmLink::publish): LCM's generated encode() reads num_seam_points rows of
// seam_world_m whatever its size, so an inconsistent detection_t would read past the vector.
core::Status encode_detection(const hwr_lcm::detection_t& detection, std::vector<uint8_t>* out,
                              const OperatorWireLimits& limits = {});
core::Status encode_operator_command(const hwr_lcm::operator_command_t& command, std::vector<uint8_t>* out,
                                     const OperatorWireLimits& limits = {});
core::Status encode_command_ack(const hwr_lcm::command_ack_t& ack, std::vector<uint8_t>* out,
                                const OperatorWireLimits& limits = {});

// Enum names for logs: "confirm" "reject" "move" "add"; "proposed" "confirmed" "rejected"; "model"
// "geometry" "operator". "unknown" for a value outside the enum.
const char* operator_command_kind_name(int kind);
const char* detection_state_name(int state);
const char* detection_source_name(int source);

}  // namespace hwr::mapio
