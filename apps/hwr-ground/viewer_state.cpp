#include "viewer_state.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <set>
#include <vector>

#include "hwr/mapio/operator_wire.hpp"

namespace hwr::ground {
namespace {

using nlohmann::json;

constexpr size_t kMaxListedKeyframes = 200;

std::string id_text(int64_t v) { return std::to_string(v); }

json matrix34(const double* T) { return json(std::vector<double>(T, T + 12)); }

// The robots anything came from, and each one's latest run (the largest run id seen).
std::map<std::string, int64_t> latest_runs(const ViewerSources& s) {
  std::map<std::string, int64_t> runs;
  for (const auto& [robot, run] : s.station.store().runs()) runs[robot] = std::max(runs[robot], run);
  for (const std::string& robot : s.telemetry.robots()) {
    const mapio::RobotTelemetry* t = s.telemetry.robot(robot);
    auto [it, added] = runs.emplace(robot, t->run_id);
    it->second = std::max(it->second, t->run_id);
  }
  for (const std::string& robot : s.console.robots()) runs.emplace(robot, -1);
  return runs;
}

json status_json(const hwr_lcm::status_t& st, int64_t received_ns) {
  json tasks = json::array();
  for (int i = 0; i < st.num_tasks; ++i) {
    tasks.push_back({{"name", st.task_name[i]},
                     {"runs", st.task_runs[i]},
                     {"overruns", st.task_overruns[i]},
                     {"slips", st.task_slips[i]}});
  }
  json counters = json::object();
  for (int i = 0; i < st.num_counters; ++i) counters[st.counter_name[i]] = st.counter_value[i];
  return {{"t_ns", id_text(st.t_ns)},
          {"received_ns", id_text(received_ns)},
          {"tasks", tasks},
          {"counters", counters}};
}

json detection_json(const hwr_lcm::detection_t& d) {
  json seam = json::array();
  for (const auto& p : d.seam_world_m) seam.push_back({p[0], p[1], p[2]});
  return {{"detection_id", id_text(d.detection_id)},
          {"segment_id", d.segment_id},
          {"keyframe_t_ns", id_text(d.keyframe_t_ns)},
          {"source", mapio::detection_source_name(d.source)},
          {"state", mapio::detection_state_name(d.state)},
          {"confidence", d.confidence},
          {"box_px", {d.box_px[0], d.box_px[1], d.box_px[2], d.box_px[3]}},
          {"center_world_m", {d.box_center_world_m[0], d.box_center_world_m[1], d.box_center_world_m[2]}},
          {"size_m", {d.box_size_m[0], d.box_size_m[1], d.box_size_m[2]}},
          {"q_world_box",
           {d.box_q_world_box[0], d.box_q_world_box[1], d.box_q_world_box[2], d.box_q_world_box[3]}},
          {"seam_world_m", seam},
          {"t_ns", id_text(d.t_ns)}};
}

json command_json(const mapio::OperatorCommandRecord& r) {
  return {{"command_id", id_text(r.command.command_id)},
          {"kind", mapio::operator_command_kind_name(r.command.kind)},
          {"detection_id", id_text(r.command.detection_id)},
          {"state", mapio::command_state_name(r.state)},
          {"reason", r.reason},
          {"result_detection_id", id_text(r.detection_id)},
          {"t_ns", id_text(r.command.t_ns)}};
}

// A number field, or an integer given as a decimal string (64-bit ids).
core::Status read_int64(const json& body, const char* field, int64_t* out) {
  auto it = body.find(field);
  if (it == body.end()) return core::InvalidArgument(std::string("command: '") + field + "' is missing");
  if (it->is_number_integer() && !(it->is_number_unsigned() && it->get<uint64_t>() > INT64_MAX)) {
    *out = it->get<int64_t>();
    return core::Status::Ok();
  }
  if (it->is_string() && parse_decimal_int64(it->get_ref<const std::string&>(), out))
    return core::Status::Ok();
  return core::InvalidArgument(std::string("command: '") + field +
                               "' must be an integer (or one as a string)");
}

template <size_t N, class T>
core::Status read_numbers(const json& body, const char* field, T (&out)[N]) {
  auto it = body.find(field);
  if (it == body.end() || !it->is_array() || it->size() != N) {
    return core::InvalidArgument(std::string("command: '") + field + "' must be an array of " +
                                 std::to_string(N) + " numbers");
  }
  for (size_t i = 0; i < N; ++i) {
    // Within T's range: a double too large for a float would be undefined behaviour to convert.
    const double v = (*it)[i].is_number() ? (*it)[i].get<double>() : std::nan("");
    if (!std::isfinite(v) || std::abs(v) > static_cast<double>(std::numeric_limits<T>::max()))
      return core::InvalidArgument(std::string("command: '") + field + "' must hold finite numbers only");
    out[i] = static_cast<T>(v);
  }
  return core::Status::Ok();
}

}  // namespace

bool parse_decimal_int64(const std::string& text, int64_t* out) {
  // Digits with an optional leading '-': no spaces, no '+', nothing after, no overflow.
  const bool negative = !text.empty() && text[0] == '-';
  if (text.size() == (negative ? 1u : 0u) || text.size() > 20) return false;
  uint64_t magnitude = 0;
  for (size_t i = negative ? 1 : 0; i < text.size(); ++i) {
    if (text[i] < '0' || text[i] > '9') return false;
    const auto digit = static_cast<uint64_t>(text[i] - '0');
    if (magnitude > (UINT64_MAX - digit) / 10) return false;
    magnitude = magnitude * 10 + digit;
  }
  const uint64_t limit = negative ? static_cast<uint64_t>(INT64_MAX) + 1 : static_cast<uint64_t>(INT64_MAX);
  if (magnitude > limit) return false;
  *out = negative ? static_cast<int64_t>(0 - magnitude) : static_cast<int64_t>(magnitude);
  return true;
}

double LinkRateMeter::update(const std::string& stream, int64_t bytes_stored, int64_t now_ns) {
  auto& s = samples_[stream];
  if (!s.empty() && bytes_stored < s.back().second) s.clear();  // the store was emptied: start again
  if (s.empty() || s.back().first < now_ns) s.emplace_back(now_ns, bytes_stored);
  while (s.size() > 2 && now_ns - s[1].first >= window_ns_) s.pop_front();
  if (s.size() < 2 || s.back().first == s.front().first) return 0.0;
  return static_cast<double>(s.back().second - s.front().second) * 1e9 /
         static_cast<double>(s.back().first - s.front().first);
}

json state_json(const ViewerSources& s, LinkRateMeter* rates, int64_t now_ns, const std::string& web_root) {
  const mapio::GroundStationStats& gs = s.station.stats();
  json robots = json::array();
  for (const auto& [robot_id, run_id] : latest_runs(s)) {
    json r = {{"robot_id", robot_id}, {"run_id", id_text(std::max<int64_t>(run_id, 0))}};
    const std::vector<hwr_lcm::detection_t> robot_detections = s.console.detections(robot_id);  // one copy
    const mapio::RobotTelemetry* t = s.telemetry.robot(robot_id);
    r["pose"] = nullptr;
    r["trajectory_poses"] = 0;
    r["status"] = nullptr;
    r["keyframes"] = json::array();
    int64_t robot_resends = -1;
    if (t != nullptr && t->run_id == run_id) {
      if (!t->trajectory.empty()) {
        const mapio::TrajectoryPose& p = t->trajectory.back();
        r["pose"] = {{"t_ns", id_text(p.t_ns)},
                     {"T_world_cam", matrix34(p.T_world_cam)},
                     {"tracking", p.tracking},
                     {"localized", p.localized}};
      }
      r["trajectory_poses"] = t->trajectory.size();
      if (t->status) {
        r["status"] = status_json(*t->status, t->status_received_ns);
        for (int i = 0; i < t->status->num_counters; ++i)
          if (t->status->counter_name[i] == "link.resends") robot_resends = t->status->counter_value[i];
      }
      // The newest kMaxListedKeyframes, and every one a detection of this run was seen on.
      std::set<int64_t> referenced;
      for (const hwr_lcm::detection_t& d : robot_detections)
        if (d.run_id == run_id) referenced.insert(d.keyframe_t_ns);
      const size_t first_newest =
          t->keyframes.size() > kMaxListedKeyframes ? t->keyframes.size() - kMaxListedKeyframes : 0;
      for (size_t i = 0; i < t->keyframes.size(); ++i) {
        const mapio::KeyframeImageInfo& kf = t->keyframes[i];
        if (i < first_newest && referenced.count(kf.keyframe_t_ns) == 0) continue;
        r["keyframes"].push_back(
            {{"t_ns", id_text(kf.keyframe_t_ns)}, {"width", kf.width}, {"height", kf.height}});
      }
    }
    // The latest run's segments and what the link brought of them.
    json segments = json::array();
    int64_t chunks = 0, bytes = 0, points = 0, missing = 0;
    if (run_id >= 0) {
      for (const mapio::GroundStore::SegmentInfo& seg : s.station.store().segments(robot_id, run_id)) {
        segments.push_back({{"run_id", id_text(run_id)},
                            {"segment_id", seg.segment_id},
                            {"version", seg.version},
                            {"points", seg.points_stored},
                            {"chunks_stored", seg.chunks_stored},
                            {"chunk_count", seg.chunk_count},
                            {"complete", seg.complete},
                            {"revision", seg.chunks_stored},
                            {"T_world_segment", matrix34(seg.T_world_segment)}});
        chunks += seg.chunks_stored;
        bytes += seg.payload_bytes_stored;
        points += seg.points_stored;
        missing += std::max(0, seg.chunk_count - seg.chunks_stored);
      }
    }
    r["segments"] = segments;
    const double age_s = gs.last_chunk_ns > 0 ? static_cast<double>(now_ns - gs.last_chunk_ns) * 1e-9 : -1.0;
    r["link"] = {{"chunks_stored", chunks},
                 {"bytes_stored", bytes},
                 {"points_stored", points},
                 {"rate_bytes_s", rates->update(robot_id + "/" + std::to_string(run_id), bytes, now_ns)},
                 {"duplicates", gs.duplicates},
                 {"rejected", gs.rejected},
                 {"missing_chunks", missing},
                 {"robot_resends", robot_resends},
                 {"last_chunk_age_s", age_s}};
    json detections = json::array();
    // The latest run's list: an earlier run's detection ids name other regions.
    for (const hwr_lcm::detection_t& d : robot_detections)
      if (d.run_id == run_id) detections.push_back(detection_json(d));
    r["detections"] = detections;
    json commands = json::array();
    for (const mapio::OperatorCommandRecord& c : s.console.commands(robot_id))
      commands.push_back(command_json(c));
    r["commands"] = commands;
    robots.push_back(std::move(r));
  }
  const mapio::GroundTelemetryStats& ts = s.telemetry.stats();
  const json server = {{"t_ns", id_text(now_ns)},
                       {"out_dir", s.station.store().out_dir()},
                       {"web_root", web_root},
                       {"telemetry_rejected", ts.rejected},
                       {"telemetry_store_errors", ts.store_errors},
                       {"operator_rejected", s.console.stats().rejected}};
  return {{"server", server}, {"robots", robots}};
}

core::Expected<json> trajectory_json(const mapio::GroundTelemetry& telemetry, const std::string& robot_id,
                                     size_t max_poses) {
  const mapio::RobotTelemetry* t = telemetry.robot(robot_id);
  if (t == nullptr || t->trajectory.empty()) return core::NotFound("no poses from robot '" + robot_id + "'");
  const size_t n = t->trajectory.size();
  const size_t step = max_poses == 0 || n <= max_poses ? 1 : (n + max_poses - 1) / max_poses;
  json times = json::array(), xyz = json::array();
  // From the newest backwards, so the current pose is always drawn.
  std::vector<size_t> picked;
  for (size_t i = n; i-- > 0;) {
    if ((n - 1 - i) % step == 0) picked.push_back(i);
  }
  std::reverse(picked.begin(), picked.end());
  for (const size_t i : picked) {
    const mapio::TrajectoryPose& p = t->trajectory[i];
    times.push_back(id_text(p.t_ns));
    xyz.push_back({p.T_world_cam[3], p.T_world_cam[7], p.T_world_cam[11]});
  }
  return json{{"robot_id", robot_id}, {"run_id", id_text(t->run_id)}, {"t_ns", times}, {"xyz", xyz}};
}

core::Expected<hwr_lcm::operator_command_t> command_from_json(const std::string& text) {
  const json body = json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (body.is_discarded() || !body.is_object())
    return core::InvalidArgument("command: the body is not a JSON object");
  hwr_lcm::operator_command_t c{};
  auto robot = body.find("robot");
  if (robot == body.end() || !robot->is_string())
    return core::InvalidArgument("command: 'robot' must be a string");
  c.robot_id = robot->get<std::string>();
  HWR_RETURN_IF_ERROR(mapio::GroundStore::validate_robot_id(c.robot_id));
  auto kind = body.find("kind");
  const std::string k = kind != body.end() && kind->is_string() ? kind->get<std::string>() : "";
  if (k == "confirm" || k == "reject" || k == "move") {
    c.kind = static_cast<int8_t>(k == "confirm"  ? mapio::OperatorCommandKind::kConfirm
                                 : k == "reject" ? mapio::OperatorCommandKind::kReject
                                                 : mapio::OperatorCommandKind::kMove);
    HWR_RETURN_IF_ERROR(read_int64(body, "detection_id", &c.detection_id));
    if (k == "move") {
      HWR_RETURN_IF_ERROR(read_numbers(body, "center_world_m", c.box_center_world_m));
      HWR_RETURN_IF_ERROR(read_numbers(body, "size_m", c.box_size_m));
      HWR_RETURN_IF_ERROR(read_numbers(body, "q_world_box", c.box_q_world_box));
    }
  } else if (k == "add") {
    c.kind = static_cast<int8_t>(mapio::OperatorCommandKind::kAdd);
    HWR_RETURN_IF_ERROR(read_int64(body, "keyframe_t_ns", &c.keyframe_t_ns));
    HWR_RETURN_IF_ERROR(read_numbers(body, "box_px", c.box_px));
    c.box_q_world_box[0] = 1.0;  // no world box: the robot lifts the rectangle with the keyframe's depth
  } else {
    return core::InvalidArgument("command: 'kind' must be confirm, reject, move or add");
  }
  return c;
}

}  // namespace hwr::ground
