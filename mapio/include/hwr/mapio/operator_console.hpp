#pragma once
// The ground station's operator library (issue #7 item 4), behind `hwr-ground --operator-input`: it
// keeps the detection list each robot streams (detection_t on HWR_DETECTION), sends the operator's
// commands (operator_command_t on HWR_OPERATOR_CMD: confirm, reject, move/resize, add a region drawn
// on a keyframe) until the robot acknowledges them (command_ack_t on HWR_OPERATOR_ACK), and keeps all
// of it on disk, so a restarted ground station shows the same list and re-sends what is still pending.
//
// Delivery: a command is persisted as pending by send(), then service() publishes it, and again every
// resend_interval_ns until an ack with its command_id arrives (the robot applies each command_id once
// and acknowledges duplicates again). A matched ack is persisted and ends the resending; a second ack
// for the same command is counted and ignored. command_id is CLOCK_REALTIME in ns at send(), raised
// to one above the largest id stored under OUT_DIR when the clock is behind it: unique for this ground
// station across restarts, and across a wiped store as long as the clock does not step back.
//
// Detections: the latest detection_t per (robot_id, detection_id): a message of a later run (larger
// run_id), or of the same run with a larger t_ns, replaces the stored one; one of an earlier run, or
// with the same or a smaller t_ns, is ignored (a repeat or a reordered message). A replayed or
// simulated run's t_ns can repeat an earlier run's, so the run comes first.
//
// Layout under OUT_DIR (beside GroundStore's run folders; robot_id [A-Za-z0-9_-]{1,64}):
//   OUT_DIR/.operator_console.lock                   flock(2): one console per folder
//   OUT_DIR/<robot_id>/operator/detections/detection_<id>.lcm   the latest detection_t, LCM-encoded
//   OUT_DIR/<robot_id>/operator/commands/command_<id>.lcm       an operator_command_t as sent
//   OUT_DIR/<robot_id>/operator/commands/ack_<id>.lcm           its command_ack_t (absent: pending)
//   OUT_DIR/<robot_id>/operator/detections.txt       the list as text, rewritten when it changes
//   OUT_DIR/<robot_id>/operator/journal.log          append-only: one line per command sent and per
//                                                    ack received, with UTC time
// <id> in decimal. Every .lcm is written as FILE.tmp, fsync'ed and renamed, then the folder fsync'ed
// (core::write_file_atomic). open() reads them back through operator_wire's bounded decoders: it
// removes *.tmp files (an interrupted write), renames a file that does not decode, fails validation or
// names another robot or id than its path to FILE.corrupt (kept for inspection, never loaded), and
// says so in OpenReport; an ack whose command is missing is noted and left alone.
//
// Not thread-safe: one thread calls every method (like GroundStation).

#include <cstdint>
#include <map>
#include <memory>
#include <set>
#include <string>
#include <vector>

#include "hwr/core/status.hpp"
#include "hwr/mapio/operator_wire.hpp"

namespace hwr::mapio {

struct OperatorConsoleConfig {
  std::string out_dir;
  OperatorWireLimits wire;
  int64_t resend_interval_ns = 500'000'000;  // a pending command is published at most this often
  // Bounds on what received messages can make the console keep (and write); beyond them a new robot
  // or a new detection id is refused (counted in stats, logged).
  int max_robots = 64;
  int max_detections_per_robot = 4096;
};

enum class CommandState { kPending, kAccepted, kRefused };
// "pending", "accepted", "refused".
const char* command_state_name(CommandState state);

// One command and what became of it.
struct OperatorCommandRecord {
  // As sent: command_id and t_ns (CLOCK_REALTIME ns) set by send(), the fields the kind ignores zeroed.
  hwr_lcm::operator_command_t command;
  CommandState state = CommandState::kPending;
  std::string reason;         // the robot's, when refused
  int64_t detection_id = -1;  // from the ack: the detection changed or created
  int64_t ack_t_ns = 0;       // the ack's t_ns (the robot's clock)
  int64_t publishes = 0;      // times published in this session
};

struct OperatorConsoleStats {
  int64_t messages = 0;            // detection and ack messages handed in
  int64_t rejected = 0;            // undecodable or invalid (last_error says why)
  int64_t detections_updated = 0;  // new detections and newer versions stored
  int64_t detections_ignored = 0;  // same or older t_ns than the stored version
  int64_t detections_refused = 0;  // over max_robots / max_detections_per_robot
  int64_t store_errors = 0;        // a file could not be written (the message is dropped)
  int64_t commands_sent = 0;       // accepted by send()
  int64_t publishes = 0;           // first sends and resends
  int64_t commands_resent = 0;     // publishes after the first of each command (this session)
  int64_t commands_acked = 0;      // acks matched to a pending command
  int64_t duplicate_acks = 0;      // for a command already acknowledged
  int64_t unmatched_acks = 0;      // for no command of this ground station (another one's, or wiped)
  std::string last_error;
};

class OperatorConsole {
 public:
  struct OpenReport {
    int64_t detections_loaded = 0;
    int64_t commands_loaded = 0;
    int64_t commands_pending = 0;  // of those loaded: published again by service()
    int64_t temp_files_removed = 0;
    int64_t corrupt_set_aside = 0;   // renamed to FILE.corrupt
    std::vector<std::string> notes;  // one line per finding, and per entry ignored
  };

  // Creates OUT_DIR if needed, takes its lock (kUnavailable while another console holds it) and
  // loads what is stored (see above). kIoError when a folder cannot be created or read.
  static core::Expected<std::unique_ptr<OperatorConsole>> open(const std::string& out_dir);
  static core::Expected<std::unique_ptr<OperatorConsole>> open(const OperatorConsoleConfig& config);
  ~OperatorConsole();
  OperatorConsole(const OperatorConsole&) = delete;
  OperatorConsole& operator=(const OperatorConsole&) = delete;

  // A received HWR_DETECTION message (bytes as received; now_ns: the caller's clock, unused but for
  // symmetry with GroundStation). Rejected messages are counted and logged, never thrown.
  void on_detection_message(const uint8_t* data, size_t size, int64_t now_ns);
  // A received HWR_OPERATOR_ACK message.
  void on_ack_message(const uint8_t* data, size_t size, int64_t now_ns);

  // Validates `command` (operator_wire's rules; robot_id must be set), zeroes the fields its kind
  // ignores, assigns command_id and t_ns, stores it as pending and journals it; service() publishes
  // it. Returns the command_id. kInvalidArgument / kOutOfRange for a malformed command (the message
  // names the field), kUnavailable when max_robots would be exceeded, kIoError when it cannot be
  // stored (then nothing is sent).
  core::Expected<int64_t> send(hwr_lcm::operator_command_t command);

  // Publishes, through publish(const operator_command_t&), every pending command not published in
  // the last resend_interval_ns (those never published in this session at once). Returns the count.
  template <class Publish>
  int service(int64_t now_ns, Publish&& publish) {
    due_.clear();
    for (const int64_t id : pending_) {
      const Command& c = commands_.at(id);
      if (c.record.publishes == 0 || now_ns - c.last_publish_ns >= config_.resend_interval_ns)
        due_.push_back(id);
    }
    // Ids copied first: publish() may hand an ack straight back (in-process transports, tests).
    int n = 0;
    for (const int64_t id : due_) {
      auto it = commands_.find(id);
      if (it == commands_.end() || it->second.record.state != CommandState::kPending) continue;
      Command& c = it->second;
      if (c.record.publishes > 0) ++stats_.commands_resent;
      ++c.record.publishes;
      c.last_publish_ns = now_ns;
      ++stats_.publishes;
      ++n;
      publish(static_cast<const hwr_lcm::operator_command_t&>(c.record.command));
    }
    return n;
  }

  // A robot's detections, sorted by detection_id (empty for an unknown robot).
  std::vector<hwr_lcm::detection_t> detections(const std::string& robot_id) const;
  // nullptr when not known. Valid until the next call that changes the console.
  const hwr_lcm::detection_t* find_detection(const std::string& robot_id, int64_t detection_id) const;
  // kNotFound for a command_id this ground station did not send (or no longer stores).
  core::Expected<OperatorCommandRecord> command(int64_t command_id) const;
  // A robot's commands, sorted by command_id.
  std::vector<OperatorCommandRecord> commands(const std::string& robot_id) const;
  int64_t pending_commands() const { return static_cast<int64_t>(pending_.size()); }
  // Robots with stored detections or commands, sorted; and those with at least one detection.
  std::vector<std::string> robots() const;
  std::vector<std::string> robots_with_detections() const;
  // Commands acknowledged since the last call, in the order the acks arrived (at most 1024 kept:
  // for a caller that reports them, e.g. hwr-ground printing each outcome).
  std::vector<OperatorCommandRecord> take_acknowledged();

  const OperatorConsoleStats& stats() const { return stats_; }
  const OpenReport& open_report() const { return report_; }
  const std::string& out_dir() const { return config_.out_dir; }
  // OUT_DIR/<robot_id>/operator
  std::string operator_dir(const std::string& robot_id) const;

 private:
  struct Command {
    OperatorCommandRecord record;
    int64_t last_publish_ns = 0;
  };
  struct Robot {
    std::map<int64_t, hwr_lcm::detection_t> detections;  // by detection_id
    std::set<int64_t> command_ids;
  };

  explicit OperatorConsole(const OperatorConsoleConfig& config);
  core::Status load();
  core::Status load_robot(const std::string& robot_id);
  void reject(const core::Status& why);
  void store_error(const core::Status& why);
  core::Status write_listing(const std::string& robot_id, const Robot& robot) const;
  void journal(const std::string& robot_id, const std::string& line);
  core::Status make_robot_dirs(const std::string& robot_id);

  OperatorConsoleConfig config_;
  int lock_fd_ = -1;
  OpenReport report_;
  OperatorConsoleStats stats_;
  std::map<std::string, Robot> robots_;
  std::map<int64_t, Command> commands_;  // by command_id, every robot
  std::set<int64_t> pending_;
  std::vector<int64_t> due_;  // service()'s scratch
  std::vector<OperatorCommandRecord> acknowledged_;
  int64_t last_command_id_ = 0;
  hwr_lcm::detection_t detection_;  // decode buffers, reused
  hwr_lcm::command_ack_t ack_;
  std::vector<uint8_t> encoded_;
};

// "confirm 4", "reject 4", "move 4", "add on keyframe 1732477000100000000": for log lines. With
// `details`, move and add also give their box ("move 4 to centre (1.3000 -0.5000 0.7500) m size
// (0.5000 0.0600 0.0600) m q (1.0000 0.0000 0.0000 0.0000)", "add on keyframe T box_px (10 20 30 40)").
std::string describe_operator_command(const hwr_lcm::operator_command_t& command, bool details = false);

}  // namespace hwr::mapio
