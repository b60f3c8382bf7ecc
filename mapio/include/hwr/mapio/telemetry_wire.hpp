#pragma once
// The wire rules of the robot's telemetry as the ground station receives it (issue #9): the camera
// pose (pose_t on HWR_POSE), the scheduler and link health (status_t on HWR_STATUS) and keyframe
// images (keyframe_image_t on HWR_KEYFRAME_IMAGE). As in operator_wire.hpp, each message is walked
// with mapio's bounded reader before LCM's generated decode() runs (LCM 1.3.1 resizes vectors to
// whatever a count says), then validated, so the viewer only ever sees messages it can draw.
//
// Validation, in this order:
//   every message     robot_id [A-Za-z0-9_-]{1,64} (GroundStore::validate_robot_id); run_id >= 0.
//   pose_t            every T_world_cam value finite, its rotation orthonormal within 1e-3
//                     (kInvalidArgument); tracking and localized 0/1 (kOutOfRange).
//   status_t          num_tasks in 0..max_tasks, num_counters in 0..max_counters, each name
//                     within max_name_bytes (checked while decoding); runs, overruns, slips and
//                     counter values >= -1 (kOutOfRange; -1 is "unknown").
//   keyframe_image_t  keyframe_t_ns >= 0; width, height, jpeg_width, jpeg_height in 1..16384
//                     (kOutOfRange); size within max_image_bytes (checked while decoding); the
//                     bytes start with a JPEG SOI marker FF D8 FF (kInvalidArgument). Whether the
//                     JPEG decodes is the viewer's affair: a browser shows a broken image, nothing
//                     worse.

#include <cstddef>
#include <cstdint>
#include <vector>

#include "hwr/core/status.hpp"
#include "hwr_lcm/keyframe_image_t.hpp"
#include "hwr_lcm/pose_t.hpp"
#include "hwr_lcm/status_t.hpp"

namespace hwr::mapio {

struct TelemetryWireLimits {
  size_t max_message_bytes = 4u << 20;  // a keyframe JPEG of up to max_image_bytes and its header
  size_t max_robot_id_bytes = 64;
  int max_tasks = 64;
  int max_counters = 256;
  size_t max_name_bytes = 64;  // status_t task and counter names
  size_t max_image_bytes = 3u << 20;
};

// Bounded decoding, then the validation above. kParseError / kOutOfRange name the field and its
// offset; `out` is overwritten (vectors keep their capacity); on error its contents are unspecified.
core::Status decode_pose(const uint8_t* data, size_t size, hwr_lcm::pose_t* out,
                         const TelemetryWireLimits& limits = {});
core::Status decode_status(const uint8_t* data, size_t size, hwr_lcm::status_t* out,
                           const TelemetryWireLimits& limits = {});
core::Status decode_keyframe_image(const uint8_t* data, size_t size, hwr_lcm::keyframe_image_t* out,
                                   const TelemetryWireLimits& limits = {});

core::Status verify_pose(const hwr_lcm::pose_t& pose, const TelemetryWireLimits& limits = {});
core::Status verify_status(const hwr_lcm::status_t& status, const TelemetryWireLimits& limits = {});
core::Status verify_keyframe_image(const hwr_lcm::keyframe_image_t& image,
                                   const TelemetryWireLimits& limits = {});

// Verifies, then LCM-encodes into `out` (resized; capacity kept): LCM's encode() reads as many
// elements as a count says, so an inconsistent status_t would read past its vectors.
core::Status encode_pose(const hwr_lcm::pose_t& pose, std::vector<uint8_t>* out,
                         const TelemetryWireLimits& limits = {});
core::Status encode_status(const hwr_lcm::status_t& status, std::vector<uint8_t>* out,
                           const TelemetryWireLimits& limits = {});
core::Status encode_keyframe_image(const hwr_lcm::keyframe_image_t& image, std::vector<uint8_t>* out,
                                   const TelemetryWireLimits& limits = {});

}  // namespace hwr::mapio
