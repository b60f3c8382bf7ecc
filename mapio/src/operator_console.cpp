#include "hwr/mapio/operator_console.hpp"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <filesystem>

#include "durable_file.hpp"
#include "hwr/core/file_io.hpp"
#include "hwr/core/log.hpp"
#include "hwr/mapio/ground_store.hpp"

namespace hwr::mapio {
namespace fs = std::filesystem;
using detail::is_dir;
using detail::is_file;
using detail::list_dir;
using detail::make_dir;

namespace {

constexpr char kLockName[] = ".operator_console.lock";
constexpr char kOperatorDir[] = "operator";
constexpr char kDetectionsDir[] = "detections";
constexpr char kCommandsDir[] = "commands";
constexpr char kTmpSuffix[] = ".tmp";  // core::write_file_atomic's temp name is PATH + ".tmp"
constexpr char kCorruptSuffix[] = ".corrupt";
constexpr size_t kMaxAcknowledgedKept = 1024;

bool ends_with(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

// "<prefix><canonical non-negative decimal>.lcm" -> the number.
bool parse_id_file(const std::string& name, const std::string& prefix, int64_t* id) {
  if (name.rfind(prefix, 0) != 0 || !ends_with(name, ".lcm")) return false;
  const std::string digits = name.substr(prefix.size(), name.size() - prefix.size() - 4);
  if (digits.empty() || digits.size() > 19) return false;
  int64_t v = 0;
  for (const char c : digits) {
    if (c < '0' || c > '9') return false;
    const int64_t d = c - '0';
    if (v > (INT64_MAX - d) / 10) return false;
    v = v * 10 + d;
  }
  *id = v;
  return digits == std::to_string(v);
}

std::string id_file(const char* prefix, int64_t id) { return prefix + std::to_string(id) + ".lcm"; }

int64_t realtime_ns() {
  timespec ts{};
  ::clock_gettime(CLOCK_REALTIME, &ts);
  return static_cast<int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

// "2024-11-24T18:30:00.123Z"
std::string utc_text(int64_t t_ns) {
  const time_t sec = static_cast<time_t>(t_ns / 1'000'000'000);
  tm utc{};
  ::gmtime_r(&sec, &utc);
  char buf[48];
  std::snprintf(buf, sizeof buf, "%04d-%02d-%02dT%02d:%02d:%02d.%03dZ", utc.tm_year + 1900, utc.tm_mon + 1,
                utc.tm_mday, utc.tm_hour, utc.tm_min, utc.tm_sec,
                static_cast<int>((t_ns % 1'000'000'000) / 1'000'000));
  return buf;
}

// Text from the robot (a refusal reason) on one line of a log: control characters become spaces.
std::string one_line(const std::string& s) {
  std::string out = s;
  for (char& c : out) {
    if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f) c = ' ';
  }
  return out;
}

// Reads one stored message and decodes it with the link's own bounded decoder. kCorruptData (what
// open() sets aside) when it is oversized or does not decode; kIoError from the file system.
template <class Msg, class Decode>
core::Status read_stored(const std::string& path, const OperatorWireLimits& limits, Decode decode, Msg* out) {
  std::error_code ec;
  const uintmax_t size = fs::file_size(path, ec);
  if (ec) return core::IoError(path + ": cannot stat: " + ec.message());
  if (size > limits.max_message_bytes) {
    return core::CorruptData(path + ": " + std::to_string(size) + " bytes, over the " +
                             std::to_string(limits.max_message_bytes) + "-byte limit of a message");
  }
  std::string bytes;
  HWR_RETURN_IF_ERROR(core::read_file(path, &bytes));
  const core::Status st = decode(reinterpret_cast<const uint8_t*>(bytes.data()), bytes.size(), out, limits);
  if (!st.ok()) return core::CorruptData(path + ": " + st.message());
  return core::Status::Ok();
}

// The fields a command's kind ignores, zeroed, so what is stored and sent says only what counts.
void clear_ignored_fields(hwr_lcm::operator_command_t* c) {
  const auto kind = static_cast<OperatorCommandKind>(c->kind);
  const bool uses_world_box = kind == OperatorCommandKind::kMove || kind == OperatorCommandKind::kAdd;
  if (kind != OperatorCommandKind::kAdd) {
    c->keyframe_t_ns = 0;
    for (float& v : c->box_px) v = 0;
  } else {
    c->detection_id = -1;
  }
  if (!uses_world_box) {
    for (double& v : c->box_center_world_m) v = 0;
    for (double& v : c->box_size_m) v = 0;
    c->box_q_world_box[0] = 1;
    c->box_q_world_box[1] = c->box_q_world_box[2] = c->box_q_world_box[3] = 0;
  }
}

std::string vec3_text(const double* v) {
  char buf[96];
  std::snprintf(buf, sizeof buf, "(%.4f %.4f %.4f)", v[0], v[1], v[2]);
  return buf;
}

}  // namespace

const char* command_state_name(CommandState state) {
  switch (state) {
    case CommandState::kPending:
      return "pending";
    case CommandState::kAccepted:
      return "accepted";
    case CommandState::kRefused:
      return "refused";
  }
  return "unknown";
}

std::string describe_operator_command(const hwr_lcm::operator_command_t& c, bool details) {
  const char* kind = operator_command_kind_name(c.kind);
  if (c.kind == static_cast<int8_t>(OperatorCommandKind::kAdd)) {
    std::string s = std::string(kind) + " on keyframe " + std::to_string(c.keyframe_t_ns);
    if (details) {
      char buf[128];
      std::snprintf(buf, sizeof buf, " box_px (%.1f %.1f %.1f %.1f)", c.box_px[0], c.box_px[1], c.box_px[2],
                    c.box_px[3]);
      s += buf;
      if (c.box_size_m[0] > 0) {
        s += " world centre " + vec3_text(c.box_center_world_m) + " m size " + vec3_text(c.box_size_m) + " m";
      }
    }
    return s;
  }
  std::string s = std::string(kind) + " " + std::to_string(c.detection_id);
  if (details && c.kind == static_cast<int8_t>(OperatorCommandKind::kMove)) {
    char q[96];
    std::snprintf(q, sizeof q, " q (%.4f %.4f %.4f %.4f)", c.box_q_world_box[0], c.box_q_world_box[1],
                  c.box_q_world_box[2], c.box_q_world_box[3]);
    s += " to centre " + vec3_text(c.box_center_world_m) + " m size " + vec3_text(c.box_size_m) + " m" + q;
  }
  return s;
}

// --- open and load ---------------------------------------------------------------------------------

OperatorConsole::OperatorConsole(const OperatorConsoleConfig& config) : config_(config) {}

OperatorConsole::~OperatorConsole() {
  if (lock_fd_ >= 0) ::close(lock_fd_);
}

core::Expected<std::unique_ptr<OperatorConsole>> OperatorConsole::open(const std::string& out_dir) {
  OperatorConsoleConfig config;
  config.out_dir = out_dir;
  return open(config);
}

core::Expected<std::unique_ptr<OperatorConsole>> OperatorConsole::open(const OperatorConsoleConfig& config) {
  if (config.out_dir.empty()) return core::InvalidArgument("operator console: empty output folder");
  if (config.resend_interval_ns <= 0 || config.max_robots < 1 || config.max_detections_per_robot < 1) {
    return core::InvalidArgument(
        "operator console: resend_interval_ns, max_robots and max_detections_per_robot must be > 0");
  }
  std::error_code ec;
  fs::create_directories(config.out_dir, ec);
  if (ec) return core::IoError(config.out_dir + ": cannot create folder: " + ec.message());
  if (!fs::is_directory(config.out_dir, ec)) return core::IoError(config.out_dir + ": not a folder");

  std::unique_ptr<OperatorConsole> c(new OperatorConsole(config));
  while (c->config_.out_dir.size() > 1 && c->config_.out_dir.back() == '/') c->config_.out_dir.pop_back();
  const std::string lock_path = c->config_.out_dir + "/" + kLockName;
  c->lock_fd_ = ::open(lock_path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  if (c->lock_fd_ < 0) return core::IoError(lock_path + ": cannot open lock file: " + std::strerror(errno));
  if (::flock(c->lock_fd_, LOCK_EX | LOCK_NB) != 0) {
    if (errno == EWOULDBLOCK) {
      return core::Unavailable(config.out_dir +
                               ": another operator console (hwr-ground) has this folder open; stop it or "
                               "use another output folder");
    }
    return core::IoError(lock_path + ": flock failed: " + std::strerror(errno));
  }
  HWR_RETURN_IF_ERROR(c->load());
  return c;
}

std::string OperatorConsole::operator_dir(const std::string& robot_id) const {
  return config_.out_dir + "/" + robot_id + "/" + kOperatorDir;
}

core::Status OperatorConsole::load() {
  std::vector<fs::directory_entry> entries;
  HWR_RETURN_IF_ERROR(list_dir(config_.out_dir, &entries));
  for (const auto& e : entries) {
    // Robot folders are GroundStore's too: only those with an operator folder are ours.
    const std::string robot_id = e.path().filename().string();
    std::error_code ec;
    if (!is_dir(e) || !fs::is_directory(operator_dir(robot_id), ec)) continue;
    if (!GroundStore::validate_robot_id(robot_id).ok()) {
      report_.notes.push_back(e.path().string() + ": not a robot folder, ignored");
      continue;
    }
    HWR_RETURN_IF_ERROR(load_robot(robot_id));
  }
  for (const auto& [id, c] : commands_) {
    if (c.record.state == CommandState::kPending) pending_.insert(id);
  }
  report_.commands_pending = static_cast<int64_t>(pending_.size());
  if (!commands_.empty()) last_command_id_ = commands_.rbegin()->first;
  for (const auto& [robot_id, robot] : robots_) {
    if (robot.detections.empty()) continue;
    const core::Status st = write_listing(robot_id, robot);  // a crash may have left it stale
    if (!st.ok()) report_.notes.push_back(st.message());
  }
  return core::Status::Ok();
}

core::Status OperatorConsole::load_robot(const std::string& robot_id) {
  Robot& robot = robots_[robot_id];
  auto note = [&](std::string line) { report_.notes.push_back(std::move(line)); };
  // Removes a temp file; renames a damaged one to FILE.corrupt. false: the entry is not a message.
  auto tidy = [&](const fs::directory_entry& e, bool* changed) -> core::Status {
    const std::string path = e.path().string();
    if (is_file(e) && ends_with(path, kTmpSuffix)) {
      if (std::remove(path.c_str()) != 0)
        return core::IoError(path + ": cannot remove: " + std::strerror(errno));
      ++report_.temp_files_removed;
      note(path + ": temp file of an interrupted write, removed");
      *changed = true;
    } else if (!(is_file(e) && ends_with(path, kCorruptSuffix))) {
      note(path + ": not an operator file, ignored");
    }
    return core::Status::Ok();
  };
  auto set_aside = [&](const std::string& path, const core::Status& why, bool* changed) -> core::Status {
    const std::string aside = path + kCorruptSuffix;
    if (std::rename(path.c_str(), aside.c_str()) != 0) {
      return core::IoError(path + ": cannot rename to " + aside + ": " + std::strerror(errno));
    }
    ++report_.corrupt_set_aside;
    note(why.message() + "; renamed to " + aside + ", not loaded");
    *changed = true;
    return core::Status::Ok();
  };

  const std::string det_dir = operator_dir(robot_id) + "/" + kDetectionsDir;
  std::error_code ec;
  if (fs::is_directory(det_dir, ec)) {
    std::vector<fs::directory_entry> entries;
    HWR_RETURN_IF_ERROR(list_dir(det_dir, &entries));
    bool changed = false;
    for (const auto& e : entries) {
      const std::string path = e.path().string();
      int64_t id = 0;
      if (!is_file(e) || !parse_id_file(e.path().filename().string(), "detection_", &id)) {
        HWR_RETURN_IF_ERROR(tidy(e, &changed));
        continue;
      }
      hwr_lcm::detection_t d;
      core::Status st = read_stored(path, config_.wire, decode_detection, &d);
      if (st.code() == core::ErrorCode::kIoError) return st;
      if (st.ok() && (d.robot_id != robot_id || d.detection_id != id)) {
        st = core::CorruptData(path + ": the message names robot " + d.robot_id + " detection " +
                               std::to_string(d.detection_id) + ", not its path");
      }
      if (!st.ok()) {
        HWR_RETURN_IF_ERROR(set_aside(path, st, &changed));
        continue;
      }
      robot.detections[id] = std::move(d);
      ++report_.detections_loaded;
    }
    if (changed) HWR_RETURN_IF_ERROR(core::fsync_directory(det_dir));
  }

  const std::string cmd_dir = operator_dir(robot_id) + "/" + kCommandsDir;
  if (fs::is_directory(cmd_dir, ec)) {
    std::vector<fs::directory_entry> entries;
    HWR_RETURN_IF_ERROR(list_dir(cmd_dir, &entries));
    bool changed = false;
    std::map<int64_t, std::string> ack_files;
    for (const auto& e : entries) {
      const std::string path = e.path().string();
      const std::string name = e.path().filename().string();
      int64_t id = 0;
      if (is_file(e) && parse_id_file(name, "ack_", &id)) {
        ack_files[id] = path;
        continue;
      }
      if (!is_file(e) || !parse_id_file(name, "command_", &id)) {
        HWR_RETURN_IF_ERROR(tidy(e, &changed));
        continue;
      }
      Command c;
      core::Status st = read_stored(path, config_.wire, decode_operator_command, &c.record.command);
      if (st.code() == core::ErrorCode::kIoError) return st;
      if (st.ok() && (c.record.command.robot_id != robot_id || c.record.command.command_id != id)) {
        st = core::CorruptData(path + ": the message names robot " + c.record.command.robot_id + " command " +
                               std::to_string(c.record.command.command_id) + ", not its path");
      }
      if (!st.ok()) {
        HWR_RETURN_IF_ERROR(set_aside(path, st, &changed));
        continue;
      }
      commands_[id] = std::move(c);
      robot.command_ids.insert(id);
      ++report_.commands_loaded;
    }
    // Acks after their commands: an ack is kept only with the command it answers.
    for (const auto& [id, path] : ack_files) {
      const auto it = commands_.find(id);
      if (it == commands_.end() || it->second.record.command.robot_id != robot_id) {
        note(path + ": acknowledgement of a command that is not stored here, ignored");
        continue;
      }
      hwr_lcm::command_ack_t a;
      core::Status st = read_stored(path, config_.wire, decode_command_ack, &a);
      if (st.code() == core::ErrorCode::kIoError) return st;
      if (st.ok() && (a.robot_id != robot_id || a.command_id != id)) {
        st = core::CorruptData(path + ": the message names robot " + a.robot_id + " command " +
                               std::to_string(a.command_id) + ", not its path");
      }
      if (!st.ok()) {
        // Without its ack the command is pending again: the robot acknowledges the resend.
        HWR_RETURN_IF_ERROR(set_aside(path, st, &changed));
        continue;
      }
      OperatorCommandRecord& r = it->second.record;
      r.state = a.accepted != 0 ? CommandState::kAccepted : CommandState::kRefused;
      r.reason = a.reason;
      r.detection_id = a.detection_id;
      r.ack_t_ns = a.t_ns;
    }
    if (changed) HWR_RETURN_IF_ERROR(core::fsync_directory(cmd_dir));
  }
  return core::Status::Ok();
}

core::Status OperatorConsole::make_robot_dirs(const std::string& robot_id) {
  const std::string robot_dir = config_.out_dir + "/" + robot_id;
  const std::string op_dir = operator_dir(robot_id);
  HWR_RETURN_IF_ERROR(make_dir(config_.out_dir, robot_dir));
  HWR_RETURN_IF_ERROR(make_dir(robot_dir, op_dir));
  HWR_RETURN_IF_ERROR(make_dir(op_dir, op_dir + "/" + kDetectionsDir));
  return make_dir(op_dir, op_dir + "/" + kCommandsDir);
}

// --- received messages -----------------------------------------------------------------------------

void OperatorConsole::reject(const core::Status& why) {
  ++stats_.rejected;
  stats_.last_error = why.message();
  HWR_LOG_WARN("operator", "message rejected: %s", why.message().c_str());
}

void OperatorConsole::store_error(const core::Status& why) {
  ++stats_.store_errors;
  stats_.last_error = why.message();
  HWR_LOG_ERROR("operator", "%s", why.message().c_str());
}

void OperatorConsole::on_detection_message(const uint8_t* data, size_t size, int64_t /*now_ns*/) {
  ++stats_.messages;
  const core::Status decoded = decode_detection(data, size, &detection_, config_.wire);
  if (!decoded.ok()) return reject(decoded);
  const hwr_lcm::detection_t& d = detection_;
  auto robot_it = robots_.find(d.robot_id);
  if (robot_it == robots_.end() && static_cast<int>(robots_.size()) >= config_.max_robots) {
    ++stats_.detections_refused;
    stats_.last_error = "detection from robot " + d.robot_id + " refused: already " +
                        std::to_string(config_.max_robots) + " robots (max_robots)";
    HWR_LOG_WARN("operator", "%s", stats_.last_error.c_str());
    return;
  }
  if (robot_it != robots_.end()) {
    const auto& known = robot_it->second.detections;
    const auto it = known.find(d.detection_id);
    // A later run's list replaces the earlier one's entry of the same id (run ids are start times; a
    // replayed run's t_ns repeat the last run's); within a run, only a newer message does.
    if (it != known.end() &&
        (d.run_id < it->second.run_id || (d.run_id == it->second.run_id && d.t_ns <= it->second.t_ns))) {
      ++stats_.detections_ignored;  // a repeat, or older than what is stored
      return;
    }
    if (it == known.end() && static_cast<int>(known.size()) >= config_.max_detections_per_robot) {
      ++stats_.detections_refused;
      stats_.last_error = "detection " + std::to_string(d.detection_id) + " of robot " + d.robot_id +
                          " refused: already " + std::to_string(config_.max_detections_per_robot) +
                          " detections (max_detections_per_robot)";
      HWR_LOG_WARN("operator", "%s", stats_.last_error.c_str());
      return;
    }
  }
  // On disk first: the list in memory never holds what a restart would not find.
  core::Status st = make_robot_dirs(d.robot_id);
  if (st.ok()) st = encode_detection(d, &encoded_, config_.wire);
  const std::string dir = operator_dir(d.robot_id) + "/" + kDetectionsDir;
  if (st.ok()) st = core::write_file_atomic(dir + "/" + id_file("detection_", d.detection_id), encoded_);
  if (st.ok()) st = core::fsync_directory(dir);
  if (!st.ok()) return store_error(st);
  Robot& robot = robots_[d.robot_id];
  robot.detections[d.detection_id] = d;
  ++stats_.detections_updated;
  st = write_listing(d.robot_id, robot);
  if (!st.ok()) store_error(st);
}

void OperatorConsole::on_ack_message(const uint8_t* data, size_t size, int64_t /*now_ns*/) {
  ++stats_.messages;
  const core::Status decoded = decode_command_ack(data, size, &ack_, config_.wire);
  if (!decoded.ok()) return reject(decoded);
  const hwr_lcm::command_ack_t& a = ack_;
  const auto it = commands_.find(a.command_id);
  if (it == commands_.end() || it->second.record.command.robot_id != a.robot_id) {
    ++stats_.unmatched_acks;  // another ground station's command, or one wiped from this store
    HWR_LOG_DEBUG("operator", "ack of command %lld from %s matches no command sent from here",
                  static_cast<long long>(a.command_id), a.robot_id.c_str());
    return;
  }
  OperatorCommandRecord& r = it->second.record;
  const CommandState state = a.accepted != 0 ? CommandState::kAccepted : CommandState::kRefused;
  if (r.state != CommandState::kPending) {
    ++stats_.duplicate_acks;  // the robot re-acknowledged a resend that crossed our ack
    if (state != r.state) {
      HWR_LOG_WARN("operator", "command %lld: a second ack says %s, the first said %s; keeping the first",
                   static_cast<long long>(a.command_id), command_state_name(state),
                   command_state_name(r.state));
    }
    return;
  }
  const std::string dir = operator_dir(a.robot_id) + "/" + kCommandsDir;
  core::Status st = encode_command_ack(a, &encoded_, config_.wire);
  if (st.ok()) st = core::write_file_atomic(dir + "/" + id_file("ack_", a.command_id), encoded_);
  if (st.ok()) st = core::fsync_directory(dir);
  if (!st.ok()) return store_error(st);  // still pending: the robot acknowledges the next resend
  r.state = state;
  r.reason = a.reason;
  r.detection_id = a.detection_id;
  r.ack_t_ns = a.t_ns;
  pending_.erase(a.command_id);
  ++stats_.commands_acked;
  if (acknowledged_.size() >= kMaxAcknowledgedKept) acknowledged_.erase(acknowledged_.begin());
  acknowledged_.push_back(r);
  std::string line = "command " + std::to_string(a.command_id) + " (" + describe_operator_command(r.command) +
                     "): " + command_state_name(state);
  if (state == CommandState::kRefused) line += ": " + one_line(r.reason);
  line += " (detection " + std::to_string(r.detection_id) + ")";
  journal(a.robot_id, line);
}

// --- commands --------------------------------------------------------------------------------------

core::Expected<int64_t> OperatorConsole::send(hwr_lcm::operator_command_t command) {
  if (command.kind < 0 || command.kind > 3) {
    return core::OutOfRange("operator command: kind " + std::to_string(command.kind) +
                            " (0 confirm, 1 reject, 2 move, 3 add)");
  }
  clear_ignored_fields(&command);
  command.command_id = 0;
  command.t_ns = 0;
  const core::Status valid = verify_operator_command(command, config_.wire);
  if (!valid.ok()) {
    // The wire's message starts "operator_command_t command_id 0: "; no id is assigned yet.
    const size_t colon = valid.message().find(": ");
    const std::string why = colon == std::string::npos ? valid.message() : valid.message().substr(colon + 2);
    return core::Status(valid.code(), std::string("operator command (") +
                                          operator_command_kind_name(command.kind) + " for robot '" +
                                          command.robot_id + "'): " + why);
  }
  const int64_t now = realtime_ns();
  command.command_id = std::max(now, last_command_id_ + 1);
  command.t_ns = now;
  if (robots_.count(command.robot_id) == 0 && static_cast<int>(robots_.size()) >= config_.max_robots) {
    return core::Unavailable("operator command for robot " + command.robot_id + ": already " +
                             std::to_string(config_.max_robots) + " robots (max_robots)");
  }
  HWR_RETURN_IF_ERROR(make_robot_dirs(command.robot_id));
  HWR_RETURN_IF_ERROR(encode_operator_command(command, &encoded_, config_.wire));
  const std::string dir = operator_dir(command.robot_id) + "/" + kCommandsDir;
  HWR_RETURN_IF_ERROR(core::write_file_atomic(dir + "/" + id_file("command_", command.command_id), encoded_));
  HWR_RETURN_IF_ERROR(core::fsync_directory(dir));

  const int64_t id = command.command_id;
  last_command_id_ = id;
  robots_[command.robot_id].command_ids.insert(id);
  Command& c = commands_[id];
  c.record = OperatorCommandRecord{};
  c.record.command = command;
  pending_.insert(id);
  ++stats_.commands_sent;
  journal(command.robot_id,
          "command " + std::to_string(id) + " (" + describe_operator_command(command, true) + "): sent");
  return id;
}

// --- listings and the journal ----------------------------------------------------------------------

core::Status OperatorConsole::write_listing(const std::string& robot_id, const Robot& robot) const {
  std::string text = "# Detections of robot " + robot_id + " as this ground station last received them (" +
                     std::to_string(robot.detections.size()) + "), written " + utc_text(realtime_ns()) +
                     ".\n# World frame, metres; size = full extents along the box's axes; seam ends = its "
                     "first and last point (- when it has none).\n"
                     "# id source state confidence centre_x centre_y centre_z size_x size_y size_z "
                     "seam_start_x seam_start_y seam_start_z seam_end_x seam_end_y seam_end_z keyframe_t_ns "
                     "t_ns\n";
  char line[512];
  for (const auto& [id, d] : robot.detections) {
    int n = std::snprintf(
        line, sizeof line, "%lld %s %s %.3f %.4f %.4f %.4f %.4f %.4f %.4f", static_cast<long long>(id),
        detection_source_name(d.source), detection_state_name(d.state), d.confidence, d.box_center_world_m[0],
        d.box_center_world_m[1], d.box_center_world_m[2], d.box_size_m[0], d.box_size_m[1], d.box_size_m[2]);
    text.append(line, static_cast<size_t>(n));
    if (d.seam_world_m.empty()) {
      text += " - - - - - -";
    } else {
      const std::vector<double>& a = d.seam_world_m.front();
      const std::vector<double>& b = d.seam_world_m.back();
      n = std::snprintf(line, sizeof line, " %.4f %.4f %.4f %.4f %.4f %.4f", a[0], a[1], a[2], b[0], b[1],
                        b[2]);
      text.append(line, static_cast<size_t>(n));
    }
    text += " " + std::to_string(d.keyframe_t_ns) + " " + std::to_string(d.t_ns) + "\n";
  }
  return core::write_file_atomic(operator_dir(robot_id) + "/detections.txt", text);
}

void OperatorConsole::journal(const std::string& robot_id, const std::string& line) {
  // Appended and fsync'ed line by line: operator commands are rare, and the journal is what a person
  // reads after the fact. Never read back, so a line cut by a crash harms nothing.
  const std::string path = operator_dir(robot_id) + "/journal.log";
  const std::string text = utc_text(realtime_ns()) + " " + one_line(line) + "\n";
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0644);
  int err = fd < 0 ? errno : core::write_all_fd(fd, text.data(), text.size());
  if (fd >= 0 && err == 0 && ::fsync(fd) != 0) err = errno;
  if (fd >= 0) ::close(fd);
  if (err != 0) store_error(core::IoError(path + ": cannot append to the journal: " + std::strerror(err)));
}

// --- accessors -------------------------------------------------------------------------------------

std::vector<hwr_lcm::detection_t> OperatorConsole::detections(const std::string& robot_id) const {
  std::vector<hwr_lcm::detection_t> out;
  const auto it = robots_.find(robot_id);
  if (it == robots_.end()) return out;
  out.reserve(it->second.detections.size());
  for (const auto& entry : it->second.detections) out.push_back(entry.second);
  return out;
}

const hwr_lcm::detection_t* OperatorConsole::find_detection(const std::string& robot_id,
                                                            int64_t detection_id) const {
  const auto it = robots_.find(robot_id);
  if (it == robots_.end()) return nullptr;
  const auto d = it->second.detections.find(detection_id);
  return d == it->second.detections.end() ? nullptr : &d->second;
}

core::Expected<OperatorCommandRecord> OperatorConsole::command(int64_t command_id) const {
  const auto it = commands_.find(command_id);
  if (it == commands_.end()) {
    return core::NotFound("command " + std::to_string(command_id) + " was not sent from this ground station");
  }
  return it->second.record;
}

std::vector<OperatorCommandRecord> OperatorConsole::commands(const std::string& robot_id) const {
  std::vector<OperatorCommandRecord> out;
  const auto it = robots_.find(robot_id);
  if (it == robots_.end()) return out;
  for (const int64_t id : it->second.command_ids) out.push_back(commands_.at(id).record);
  return out;
}

std::vector<std::string> OperatorConsole::robots() const {
  std::vector<std::string> out;
  for (const auto& [id, robot] : robots_) {
    if (!robot.detections.empty() || !robot.command_ids.empty()) out.push_back(id);
  }
  return out;
}

std::vector<std::string> OperatorConsole::robots_with_detections() const {
  std::vector<std::string> out;
  for (const auto& [id, robot] : robots_) {
    if (!robot.detections.empty()) out.push_back(id);
  }
  return out;
}

std::vector<OperatorCommandRecord> OperatorConsole::take_acknowledged() {
  std::vector<OperatorCommandRecord> out;
  out.swap(acknowledged_);
  return out;
}

}  // namespace hwr::mapio
