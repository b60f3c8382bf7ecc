// libFuzzer target: arbitrary bytes as a received operator-channel message (operator_wire.hpp). The
// first byte picks the decoder, as the channel would (0 HWR_DETECTION: decode_detection, 1
// HWR_OPERATOR_CMD: decode_operator_command, 2 HWR_OPERATOR_ACK: decode_command_ack; its value
// modulo 3); the rest is the message. Seeds: make_operator_seeds.cpp. Findings: a crash, a sanitizer
// report, an allocation over the limits, a rejection without a message, a decoded message that does
// not re-encode to the same bytes or breaks the limits or
// the enum ranges.

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <vector>

#include "hwr/mapio/operator_wire.hpp"

namespace {

// Decoded messages are valid by contract: the verified encoder must give the input back.
// True when the message decoded (then checked); false when it was rejected.
template <class Msg, class Decode, class Encode>
bool round_trip(const uint8_t* data, size_t size, Msg* msg, Decode decode, Encode encode) {
  static std::vector<uint8_t> again;
  const hwr::mapio::OperatorWireLimits limits;
  const hwr::core::Status decoded = decode(data, size, msg, limits);
  if (!decoded.ok()) {
    if (decoded.message().empty()) std::abort();  // every rejection says why
    return false;
  }
  if (!encode(*msg, &again, limits).ok()) std::abort();
  if (again.size() != size || std::memcmp(again.data(), data, size) != 0) std::abort();
  if (msg->robot_id.empty() || msg->robot_id.size() > limits.max_robot_id_bytes) std::abort();
  return true;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  static hwr_lcm::detection_t detection;  // reused across inputs, as a receiver does
  static hwr_lcm::operator_command_t command;
  static hwr_lcm::command_ack_t ack;
  const hwr::mapio::OperatorWireLimits limits;
  switch (data[0] % 3) {
    case 0:
      if (!round_trip(data + 1, size - 1, &detection, hwr::mapio::decode_detection,
                      hwr::mapio::encode_detection)) {
        break;
      }
      if (detection.seam_world_m.size() > static_cast<size_t>(limits.max_seam_points)) std::abort();
      if (detection.state < 0 || detection.state > 2 || detection.source < 0 || detection.source > 2) {
        std::abort();
      }
      break;
    case 1:
      if (!round_trip(data + 1, size - 1, &command, hwr::mapio::decode_operator_command,
                      hwr::mapio::encode_operator_command)) {
        break;
      }
      if (command.kind < 0 || command.kind > 3) std::abort();
      break;
    default:
      if (!round_trip(data + 1, size - 1, &ack, hwr::mapio::decode_command_ack,
                      hwr::mapio::encode_command_ack)) {
        break;
      }
      if (ack.reason.size() > limits.max_reason_bytes || (ack.accepted != 0 && ack.accepted != 1)) {
        std::abort();
      }
      break;
  }
  return 0;
}
