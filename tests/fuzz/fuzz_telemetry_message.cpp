// libFuzzer target: arbitrary bytes as a received telemetry message (telemetry_wire.hpp), what the
// ground station's viewer takes from the robot. The first byte picks the decoder, as the channel would
// (its value modulo 3: 0 HWR_POSE decode_pose, 1 HWR_STATUS decode_status, 2 HWR_KEYFRAME_IMAGE
// decode_keyframe_image); the rest is the message. Seeds: make_telemetry_seeds.cpp. Findings: a crash,
// a sanitizer report, an allocation over the limits, a rejection without a message, or a decoded
// message that does not re-encode to the same bytes or breaks the limits.

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <vector>

#include "hwr/mapio/telemetry_wire.hpp"

namespace {

// Decoded messages are valid by contract: the verified encoder must give the input back.
template <class Msg, class Decode, class Encode>
bool round_trip(const uint8_t* data, size_t size, Msg* msg, Decode decode, Encode encode) {
  static std::vector<uint8_t> again;
  const hwr::mapio::TelemetryWireLimits limits;
  const hwr::core::Status decoded = decode(data, size, msg, limits);
  if (!decoded.ok()) {
    if (decoded.message().empty()) std::abort();  // every rejection says why
    return false;
  }
  if (!encode(*msg, &again, limits).ok()) std::abort();
  if (again.size() != size || std::memcmp(again.data(), data, size) != 0) std::abort();
  if (msg->robot_id.empty() || msg->robot_id.size() > limits.max_robot_id_bytes || msg->run_id < 0)
    std::abort();
  return true;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  static hwr_lcm::pose_t pose;  // reused across inputs, as a receiver does
  static hwr_lcm::status_t status;
  static hwr_lcm::keyframe_image_t image;
  const hwr::mapio::TelemetryWireLimits limits;
  switch (data[0] % 3) {
    case 0:
      if (round_trip(data + 1, size - 1, &pose, hwr::mapio::decode_pose, hwr::mapio::encode_pose) &&
          (pose.tracking > 1 || pose.localized > 1 || pose.tracking < 0 || pose.localized < 0)) {
        std::abort();
      }
      break;
    case 1:
      if (round_trip(data + 1, size - 1, &status, hwr::mapio::decode_status, hwr::mapio::encode_status) &&
          (status.task_name.size() > static_cast<size_t>(limits.max_tasks) ||
           status.counter_name.size() > static_cast<size_t>(limits.max_counters))) {
        std::abort();
      }
      break;
    default:
      if (round_trip(data + 1, size - 1, &image, hwr::mapio::decode_keyframe_image,
                     hwr::mapio::encode_keyframe_image) &&
          (image.jpeg.size() > limits.max_image_bytes || image.jpeg.size() < 3 || image.width < 1)) {
        std::abort();
      }
      break;
  }
  return 0;
}
