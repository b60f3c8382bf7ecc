#include "hwr/mapio/operator_wire.hpp"

#include <cmath>
#include <cstdio>
#include <string>

#include "lcm_reader.hpp"

namespace hwr::mapio {
namespace {

using detail::BeReader;

constexpr const char* kDetection = "detection_t";
constexpr const char* kCommand = "operator_command_t";
constexpr const char* kAck = "command_ack_t";

std::string id_text(const char* type, const char* id_name, int64_t id) {
  return std::string(type) + " " + id_name + " " + std::to_string(id);
}

bool robot_id_char(char c) {
  return (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '_' || c == '-';
}

core::Status check_robot_id(const std::string& robot_id, const OperatorWireLimits& limits,
                            const std::string& where) {
  if (robot_id.empty()) return core::OutOfRange(where + ": robot_id is empty");
  if (robot_id.size() > limits.max_robot_id_bytes) {
    return core::OutOfRange(where + ": robot_id has " + std::to_string(robot_id.size()) +
                            " bytes, more than the limit of " + std::to_string(limits.max_robot_id_bytes));
  }
  for (const char c : robot_id) {
    if (!robot_id_char(c)) {
      return core::InvalidArgument(where + ": robot_id may hold only A-Z a-z 0-9 _ - (it names folders)");
    }
  }
  return core::Status::Ok();
}

template <class T>
core::Status check_finite(const T* v, int n, const std::string& where, const char* field) {
  for (int i = 0; i < n; ++i) {
    if (!std::isfinite(v[i])) {
      return core::InvalidArgument(where + ": " + field + "[" + std::to_string(i) + "] is not finite");
    }
  }
  return core::Status::Ok();
}

core::Status check_unit_quaternion(const double q[4], const std::string& where) {
  const double norm = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
  if (std::fabs(norm - 1.0) > kUnitQuaternionTolerance) {
    return core::InvalidArgument(where + ": box_q_world_box has norm " + std::to_string(norm) +
                                 ", not a unit quaternion (tolerance 1e-3)");
  }
  return core::Status::Ok();
}

// The box fields every message type shares, all finite.
template <class Msg>
core::Status check_box_finite(const Msg& m, const std::string& where) {
  HWR_RETURN_IF_ERROR(check_finite(m.box_px, 4, where, "box_px"));
  HWR_RETURN_IF_ERROR(check_finite(m.box_center_world_m, 3, where, "box_center_world_m"));
  HWR_RETURN_IF_ERROR(check_finite(m.box_size_m, 3, where, "box_size_m"));
  return check_finite(m.box_q_world_box, 4, where, "box_q_world_box");
}

std::string sizes_text(const double s[3]) {
  char buf[96];
  std::snprintf(buf, sizeof buf, "%g %g %g", s[0], s[1], s[2]);
  return buf;
}

std::string px_text(const float b[4]) {
  char buf[96];
  std::snprintf(buf, sizeof buf, "%g %g %g %g", b[0], b[1], b[2], b[3]);
  return buf;
}

}  // namespace

const char* operator_command_kind_name(int kind) {
  switch (kind) {
    case 0:
      return "confirm";
    case 1:
      return "reject";
    case 2:
      return "move";
    case 3:
      return "add";
    default:
      return "unknown";
  }
}

const char* detection_state_name(int state) {
  switch (state) {
    case 0:
      return "proposed";
    case 1:
      return "confirmed";
    case 2:
      return "rejected";
    default:
      return "unknown";
  }
}

const char* detection_source_name(int source) {
  switch (source) {
    case 0:
      return "model";
    case 1:
      return "geometry";
    case 2:
      return "operator";
    default:
      return "unknown";
  }
}

// --- validation ------------------------------------------------------------------------------------

core::Status verify_detection(const hwr_lcm::detection_t& d, const OperatorWireLimits& limits) {
  const std::string where = id_text(kDetection, "detection_id", d.detection_id);
  HWR_RETURN_IF_ERROR(check_robot_id(d.robot_id, limits, where));
  if (!std::isfinite(d.confidence)) return core::InvalidArgument(where + ": confidence is not finite");
  HWR_RETURN_IF_ERROR(check_box_finite(d, where));
  if (d.num_seam_points < 0 || d.num_seam_points > limits.max_seam_points) {
    return core::OutOfRange(where + ": num_seam_points " + std::to_string(d.num_seam_points) +
                            ", allowed 0.." + std::to_string(limits.max_seam_points));
  }
  if (static_cast<size_t>(d.num_seam_points) != d.seam_world_m.size()) {
    return core::InvalidArgument(where + ": num_seam_points " + std::to_string(d.num_seam_points) + " but " +
                                 std::to_string(d.seam_world_m.size()) + " rows in seam_world_m");
  }
  for (size_t i = 0; i < d.seam_world_m.size(); ++i) {
    const std::vector<double>& p = d.seam_world_m[i];
    if (p.size() != 3) {
      return core::InvalidArgument(where + ": seam_world_m[" + std::to_string(i) + "] has " +
                                   std::to_string(p.size()) + " values, not 3");
    }
    HWR_RETURN_IF_ERROR(
        check_finite(p.data(), 3, where, ("seam_world_m[" + std::to_string(i) + "]").c_str()));
  }
  if (d.detection_id < 0) return core::OutOfRange(where + ": detection_id must be >= 0");
  if (d.source < 0 || d.source > 2) {
    return core::OutOfRange(where + ": source " + std::to_string(d.source) +
                            " (0 model, 1 geometry, 2 operator)");
  }
  if (d.state < 0 || d.state > 2) {
    return core::OutOfRange(where + ": state " + std::to_string(d.state) +
                            " (0 proposed, 1 confirmed, 2 rejected)");
  }
  if (!(d.confidence >= 0.0f && d.confidence <= 1.0f)) {
    return core::OutOfRange(where + ": confidence " + std::to_string(d.confidence) + " outside [0, 1]");
  }
  if (d.box_px[2] < 0 || d.box_px[3] < 0) {
    return core::OutOfRange(where + ": box_px " + px_text(d.box_px) + ": width and height must be >= 0");
  }
  if (d.box_size_m[0] < 0 || d.box_size_m[1] < 0 || d.box_size_m[2] < 0) {
    return core::OutOfRange(where + ": box_size_m " + sizes_text(d.box_size_m) + " must be >= 0");
  }
  return check_unit_quaternion(d.box_q_world_box, where);
}

core::Status verify_operator_command(const hwr_lcm::operator_command_t& c, const OperatorWireLimits& limits) {
  const std::string where = id_text(kCommand, "command_id", c.command_id);
  HWR_RETURN_IF_ERROR(check_robot_id(c.robot_id, limits, where));
  HWR_RETURN_IF_ERROR(check_box_finite(c, where));
  if (c.command_id < 0) return core::OutOfRange(where + ": command_id must be >= 0");
  const auto kind = static_cast<OperatorCommandKind>(c.kind);
  switch (kind) {
    case OperatorCommandKind::kConfirm:
    case OperatorCommandKind::kReject:
      break;
    case OperatorCommandKind::kMove:
      if (!(c.box_size_m[0] > 0 && c.box_size_m[1] > 0 && c.box_size_m[2] > 0)) {
        return core::OutOfRange(where + ": move needs box_size_m > 0 on each axis, got " +
                                sizes_text(c.box_size_m));
      }
      HWR_RETURN_IF_ERROR(check_unit_quaternion(c.box_q_world_box, where));
      break;
    case OperatorCommandKind::kAdd: {
      if (c.box_px[0] < 0 || c.box_px[1] < 0 || !(c.box_px[2] > 0) || !(c.box_px[3] > 0)) {
        return core::OutOfRange(where + ": add needs box_px x, y >= 0 and width, height > 0, got " +
                                px_text(c.box_px));
      }
      const double* s = c.box_size_m;
      const bool no_world_box = s[0] == 0 && s[1] == 0 && s[2] == 0;
      if (!no_world_box) {
        if (!(s[0] > 0 && s[1] > 0 && s[2] > 0)) {
          return core::OutOfRange(where +
                                  ": add's world box needs box_size_m > 0 on each axis (or all 0 for "
                                  "none), got " +
                                  sizes_text(s));
        }
        HWR_RETURN_IF_ERROR(check_unit_quaternion(c.box_q_world_box, where));
      }
      return core::Status::Ok();  // detection_id is ignored for add
    }
    default:
      return core::OutOfRange(where + ": kind " + std::to_string(c.kind) +
                              " (0 confirm, 1 reject, 2 move, 3 add)");
  }
  if (c.detection_id < 0) {
    return core::OutOfRange(where + ": " + operator_command_kind_name(c.kind) +
                            " needs a detection_id >= 0, got " + std::to_string(c.detection_id));
  }
  return core::Status::Ok();
}

core::Status verify_command_ack(const hwr_lcm::command_ack_t& a, const OperatorWireLimits& limits) {
  const std::string where = id_text(kAck, "command_id", a.command_id);
  HWR_RETURN_IF_ERROR(check_robot_id(a.robot_id, limits, where));
  if (a.command_id < 0) return core::OutOfRange(where + ": command_id must be >= 0");
  if (a.accepted != 0 && a.accepted != 1) {
    return core::OutOfRange(where + ": accepted " + std::to_string(a.accepted) + " must be 0 or 1");
  }
  if (a.reason.size() > limits.max_reason_bytes) {
    return core::OutOfRange(where + ": reason of " + std::to_string(a.reason.size()) +
                            " bytes, more than the limit of " + std::to_string(limits.max_reason_bytes));
  }
  if (a.reason.find('\0') != std::string::npos) {
    return core::InvalidArgument(where + ": reason contains a NUL byte");
  }
  return core::Status::Ok();
}

// --- decoding --------------------------------------------------------------------------------------

core::Status decode_detection(const uint8_t* data, size_t size, hwr_lcm::detection_t* out,
                              const OperatorWireLimits& limits) {
  HWR_RETURN_IF_ERROR(detail::check_message_size(data, size, limits.max_message_bytes, kDetection));
  // Walk the encoding (detection_t.lcm order) and bound every length before LCM sees it.
  BeReader r(data, size, kDetection);
  HWR_RETURN_IF_ERROR(r.check_fingerprint(hwr_lcm::detection_t::getHash()));
  HWR_RETURN_IF_ERROR(r.skip(8, "t_ns"));
  HWR_RETURN_IF_ERROR(r.string(limits.max_robot_id_bytes, "robot_id"));
  // run_id, detection_id, segment_id, keyframe_t_ns, source, state, confidence, box_px,
  // box_center_world_m, box_size_m, box_q_world_box.
  HWR_RETURN_IF_ERROR(r.skip(8 + 8 + 4 + 8 + 1 + 1 + 4 + 4 * 4 + 3 * 8 + 3 * 8 + 4 * 8, "detection fields"));
  const size_t num_at = r.pos();
  int32_t num_seam_points = 0;
  HWR_RETURN_IF_ERROR(r.i32(&num_seam_points, "num_seam_points"));
  if (num_seam_points < 0 || num_seam_points > limits.max_seam_points) {
    return core::OutOfRange("detection_t: num_seam_points " + std::to_string(num_seam_points) +
                            " at offset " + std::to_string(num_at) + ", allowed 0.." +
                            std::to_string(limits.max_seam_points));
  }
  HWR_RETURN_IF_ERROR(r.skip(3 * 8 * static_cast<size_t>(num_seam_points), "seam_world_m"));
  HWR_RETURN_IF_ERROR(r.check_end());
  HWR_RETURN_IF_ERROR(detail::decode_walked(data, size, kDetection, out));
  return verify_detection(*out, limits);
}

core::Status decode_operator_command(const uint8_t* data, size_t size, hwr_lcm::operator_command_t* out,
                                     const OperatorWireLimits& limits) {
  HWR_RETURN_IF_ERROR(detail::check_message_size(data, size, limits.max_message_bytes, kCommand));
  BeReader r(data, size, kCommand);
  HWR_RETURN_IF_ERROR(r.check_fingerprint(hwr_lcm::operator_command_t::getHash()));
  HWR_RETURN_IF_ERROR(r.skip(8, "t_ns"));
  HWR_RETURN_IF_ERROR(r.string(limits.max_robot_id_bytes, "robot_id"));
  // command_id, kind, detection_id, keyframe_t_ns, box_px, box_center_world_m, box_size_m,
  // box_q_world_box.
  HWR_RETURN_IF_ERROR(r.skip(8 + 1 + 8 + 8 + 4 * 4 + 3 * 8 + 3 * 8 + 4 * 8, "command fields"));
  HWR_RETURN_IF_ERROR(r.check_end());
  HWR_RETURN_IF_ERROR(detail::decode_walked(data, size, kCommand, out));
  return verify_operator_command(*out, limits);
}

core::Status decode_command_ack(const uint8_t* data, size_t size, hwr_lcm::command_ack_t* out,
                                const OperatorWireLimits& limits) {
  HWR_RETURN_IF_ERROR(detail::check_message_size(data, size, limits.max_message_bytes, kAck));
  BeReader r(data, size, kAck);
  HWR_RETURN_IF_ERROR(r.check_fingerprint(hwr_lcm::command_ack_t::getHash()));
  HWR_RETURN_IF_ERROR(r.skip(8, "t_ns"));
  HWR_RETURN_IF_ERROR(r.string(limits.max_robot_id_bytes, "robot_id"));
  HWR_RETURN_IF_ERROR(r.skip(8 + 1, "command_id, accepted"));
  HWR_RETURN_IF_ERROR(r.string(limits.max_reason_bytes, "reason"));
  HWR_RETURN_IF_ERROR(r.skip(8, "detection_id"));
  HWR_RETURN_IF_ERROR(r.check_end());
  HWR_RETURN_IF_ERROR(detail::decode_walked(data, size, kAck, out));
  return verify_command_ack(*out, limits);
}

// --- encoding --------------------------------------------------------------------------------------

core::Status encode_detection(const hwr_lcm::detection_t& detection, std::vector<uint8_t>* out,
                              const OperatorWireLimits& limits) {
  HWR_RETURN_IF_ERROR(verify_detection(detection, limits));
  return detail::encode_lcm(detection, kDetection, out);
}

core::Status encode_operator_command(const hwr_lcm::operator_command_t& command, std::vector<uint8_t>* out,
                                     const OperatorWireLimits& limits) {
  HWR_RETURN_IF_ERROR(verify_operator_command(command, limits));
  return detail::encode_lcm(command, kCommand, out);
}

core::Status encode_command_ack(const hwr_lcm::command_ack_t& ack, std::vector<uint8_t>* out,
                                const OperatorWireLimits& limits) {
  HWR_RETURN_IF_ERROR(verify_command_ack(ack, limits));
  return detail::encode_lcm(ack, kAck, out);
}

}  // namespace hwr::mapio
