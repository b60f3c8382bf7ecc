#include "hwr/mapio/telemetry_wire.hpp"

#include <cmath>
#include <string>

#include <Eigen/Core>
#include <Eigen/LU>

#include "hwr/mapio/ground_store.hpp"
#include "lcm_reader.hpp"

namespace hwr::mapio {
namespace {

using detail::BeReader;

constexpr const char* kPose = "pose_t";
constexpr const char* kStatus = "status_t";
constexpr const char* kImage = "keyframe_image_t";
constexpr int kMaxImageSide = 16384;

core::Status check_common(const std::string& robot_id, int64_t run_id, const char* type) {
  const core::Status st = GroundStore::validate_robot_id(robot_id);
  if (!st.ok()) return core::Status(st.code(), std::string(type) + ": " + st.message());
  if (run_id < 0) return core::OutOfRange(std::string(type) + ": run_id " + std::to_string(run_id) + " < 0");
  return core::Status::Ok();
}

// A count field of at most `max` elements.
core::Status count(BeReader* r, int max, const char* field, int32_t* n) {
  HWR_RETURN_IF_ERROR(r->i32(n, field));
  if (*n < 0 || *n > max) {
    return core::OutOfRange(std::string(field) + " " + std::to_string(*n) + " outside 0.." +
                            std::to_string(max));
  }
  return core::Status::Ok();
}

core::Status check_side(int32_t v, const char* field) {
  if (v < 1 || v > kMaxImageSide) {
    return core::OutOfRange(std::string(kImage) + ": " + field + " " + std::to_string(v) + " outside 1.." +
                            std::to_string(kMaxImageSide));
  }
  return core::Status::Ok();
}

}  // namespace

core::Status verify_pose(const hwr_lcm::pose_t& p, const TelemetryWireLimits&) {
  HWR_RETURN_IF_ERROR(check_common(p.robot_id, p.run_id, kPose));
  Eigen::Matrix3d R;
  for (int i = 0; i < 12; ++i) {
    if (!std::isfinite(p.T_world_cam[i])) {
      return core::InvalidArgument(std::string(kPose) + ": T_world_cam[" + std::to_string(i) +
                                   "] is not finite");
    }
    if (i % 4 < 3) R(i / 4, i % 4) = p.T_world_cam[i];
  }
  if (!(R.transpose() * R).isApprox(Eigen::Matrix3d::Identity(), 1e-3) ||
      std::abs(R.determinant() - 1) > 1e-3) {
    return core::InvalidArgument(std::string(kPose) + ": T_world_cam's rotation is not orthonormal");
  }
  if ((p.tracking != 0 && p.tracking != 1) || (p.localized != 0 && p.localized != 1)) {
    return core::OutOfRange(std::string(kPose) + ": tracking and localized must be 0 or 1");
  }
  return core::Status::Ok();
}

core::Status verify_status(const hwr_lcm::status_t& s, const TelemetryWireLimits& limits) {
  HWR_RETURN_IF_ERROR(check_common(s.robot_id, s.run_id, kStatus));
  const auto n_tasks = static_cast<size_t>(std::max(s.num_tasks, 0));
  if (s.num_tasks < 0 || s.num_tasks > limits.max_tasks || s.task_name.size() != n_tasks ||
      s.task_runs.size() != n_tasks || s.task_overruns.size() != n_tasks || s.task_slips.size() != n_tasks) {
    return core::OutOfRange(std::string(kStatus) + ": num_tasks " + std::to_string(s.num_tasks) +
                            " disagrees with its arrays or is outside 0.." +
                            std::to_string(limits.max_tasks));
  }
  const auto n_counters = static_cast<size_t>(std::max(s.num_counters, 0));
  if (s.num_counters < 0 || s.num_counters > limits.max_counters || s.counter_name.size() != n_counters ||
      s.counter_value.size() != n_counters) {
    return core::OutOfRange(std::string(kStatus) + ": num_counters " + std::to_string(s.num_counters) +
                            " disagrees with its arrays or is outside 0.." +
                            std::to_string(limits.max_counters));
  }
  auto names_ok = [&](const std::vector<std::string>& names) {
    for (const std::string& n : names)
      if (n.size() > limits.max_name_bytes || n.find('\0') != std::string::npos) return false;
    return true;
  };
  if (!names_ok(s.task_name) || !names_ok(s.counter_name)) {
    return core::OutOfRange(std::string(kStatus) + ": a name is longer than " +
                            std::to_string(limits.max_name_bytes) + " bytes or holds a NUL");
  }
  for (size_t i = 0; i < n_tasks; ++i) {
    if (s.task_runs[i] < -1 || s.task_overruns[i] < -1 || s.task_slips[i] < -1)
      return core::OutOfRange(std::string(kStatus) + ": task " + s.task_name[i] + " has a count below -1");
  }
  for (size_t i = 0; i < n_counters; ++i) {
    if (s.counter_value[i] < -1)
      return core::OutOfRange(std::string(kStatus) + ": counter " + s.counter_name[i] + " is below -1");
  }
  return core::Status::Ok();
}

core::Status verify_keyframe_image(const hwr_lcm::keyframe_image_t& m, const TelemetryWireLimits& limits) {
  HWR_RETURN_IF_ERROR(check_common(m.robot_id, m.run_id, kImage));
  if (m.keyframe_t_ns < 0) return core::OutOfRange(std::string(kImage) + ": keyframe_t_ns < 0");
  HWR_RETURN_IF_ERROR(check_side(m.width, "width"));
  HWR_RETURN_IF_ERROR(check_side(m.height, "height"));
  HWR_RETURN_IF_ERROR(check_side(m.jpeg_width, "jpeg_width"));
  HWR_RETURN_IF_ERROR(check_side(m.jpeg_height, "jpeg_height"));
  if (m.size < 0 || static_cast<size_t>(m.size) != m.jpeg.size() ||
      static_cast<size_t>(m.size) > limits.max_image_bytes) {
    return core::OutOfRange(std::string(kImage) + ": size " + std::to_string(m.size) +
                            " disagrees with the bytes or is over the limit of " +
                            std::to_string(limits.max_image_bytes));
  }
  if (m.jpeg.size() < 3 || m.jpeg[0] != 0xFF || m.jpeg[1] != 0xD8 || m.jpeg[2] != 0xFF) {
    return core::InvalidArgument(std::string(kImage) + ": the bytes are not a JPEG (no SOI marker)");
  }
  return core::Status::Ok();
}

core::Status decode_pose(const uint8_t* data, size_t size, hwr_lcm::pose_t* out,
                         const TelemetryWireLimits& limits) {
  HWR_RETURN_IF_ERROR(detail::check_message_size(data, size, limits.max_message_bytes, kPose));
  BeReader r(data, size, kPose);
  HWR_RETURN_IF_ERROR(r.check_fingerprint(hwr_lcm::pose_t::getHash()));
  HWR_RETURN_IF_ERROR(r.skip(8, "t_ns"));
  HWR_RETURN_IF_ERROR(r.string(limits.max_robot_id_bytes, "robot_id"));
  HWR_RETURN_IF_ERROR(r.skip(8 + 12 * 8 + 1 + 1, "run_id, T_world_cam, tracking, localized"));
  HWR_RETURN_IF_ERROR(r.check_end());
  HWR_RETURN_IF_ERROR(detail::decode_walked(data, size, kPose, out));
  return verify_pose(*out, limits);
}

core::Status decode_status(const uint8_t* data, size_t size, hwr_lcm::status_t* out,
                           const TelemetryWireLimits& limits) {
  HWR_RETURN_IF_ERROR(detail::check_message_size(data, size, limits.max_message_bytes, kStatus));
  BeReader r(data, size, kStatus);
  HWR_RETURN_IF_ERROR(r.check_fingerprint(hwr_lcm::status_t::getHash()));
  HWR_RETURN_IF_ERROR(r.skip(8, "t_ns"));
  HWR_RETURN_IF_ERROR(r.string(limits.max_robot_id_bytes, "robot_id"));
  HWR_RETURN_IF_ERROR(r.skip(8, "run_id"));
  int32_t tasks = 0;
  HWR_RETURN_IF_ERROR(count(&r, limits.max_tasks, "num_tasks", &tasks));
  for (int32_t i = 0; i < tasks; ++i) HWR_RETURN_IF_ERROR(r.string(limits.max_name_bytes, "task_name"));
  HWR_RETURN_IF_ERROR(r.skip(static_cast<size_t>(tasks) * 8 * 3, "task_runs, task_overruns, task_slips"));
  int32_t counters = 0;
  HWR_RETURN_IF_ERROR(count(&r, limits.max_counters, "num_counters", &counters));
  for (int32_t i = 0; i < counters; ++i) HWR_RETURN_IF_ERROR(r.string(limits.max_name_bytes, "counter_name"));
  HWR_RETURN_IF_ERROR(r.skip(static_cast<size_t>(counters) * 8, "counter_value"));
  HWR_RETURN_IF_ERROR(r.check_end());
  HWR_RETURN_IF_ERROR(detail::decode_walked(data, size, kStatus, out));
  return verify_status(*out, limits);
}

core::Status decode_keyframe_image(const uint8_t* data, size_t size, hwr_lcm::keyframe_image_t* out,
                                   const TelemetryWireLimits& limits) {
  HWR_RETURN_IF_ERROR(detail::check_message_size(data, size, limits.max_message_bytes, kImage));
  BeReader r(data, size, kImage);
  HWR_RETURN_IF_ERROR(r.check_fingerprint(hwr_lcm::keyframe_image_t::getHash()));
  HWR_RETURN_IF_ERROR(r.skip(8, "t_ns"));
  HWR_RETURN_IF_ERROR(r.string(limits.max_robot_id_bytes, "robot_id"));
  HWR_RETURN_IF_ERROR(r.skip(8 + 8 + 4 * 4, "run_id, keyframe_t_ns, width, height, jpeg_width, jpeg_height"));
  int32_t bytes = 0;
  HWR_RETURN_IF_ERROR(r.i32(&bytes, "size"));
  if (bytes < 0 || static_cast<size_t>(bytes) > limits.max_image_bytes) {
    return core::OutOfRange(std::string(kImage) + ": size " + std::to_string(bytes) + " outside 0.." +
                            std::to_string(limits.max_image_bytes));
  }
  HWR_RETURN_IF_ERROR(r.skip(static_cast<size_t>(bytes), "jpeg"));
  HWR_RETURN_IF_ERROR(r.check_end());
  HWR_RETURN_IF_ERROR(detail::decode_walked(data, size, kImage, out));
  return verify_keyframe_image(*out, limits);
}

core::Status encode_pose(const hwr_lcm::pose_t& pose, std::vector<uint8_t>* out,
                         const TelemetryWireLimits& limits) {
  HWR_RETURN_IF_ERROR(verify_pose(pose, limits));
  return detail::encode_lcm(pose, kPose, out);
}

core::Status encode_status(const hwr_lcm::status_t& status, std::vector<uint8_t>* out,
                           const TelemetryWireLimits& limits) {
  HWR_RETURN_IF_ERROR(verify_status(status, limits));
  return detail::encode_lcm(status, kStatus, out);
}

core::Status encode_keyframe_image(const hwr_lcm::keyframe_image_t& image, std::vector<uint8_t>* out,
                                   const TelemetryWireLimits& limits) {
  HWR_RETURN_IF_ERROR(verify_keyframe_image(image, limits));
  return detail::encode_lcm(image, kImage, out);
}

}  // namespace hwr::mapio
