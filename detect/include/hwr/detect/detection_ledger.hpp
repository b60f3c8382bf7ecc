#pragma once
// The robot's list of welding regions and the operator's corrections to it (issue #7 item 4; the
// paper stresses that automatic detection needs a person to check it). Each entry is one welding
// region of the map: what a detector proposed (its box merged over keyframes by the fine region map,
// recon/fine_region_map.hpp) or what the operator drew, with a state (proposed, confirmed, rejected)
// and a stable id that the ground station addresses (mapio detection_t / operator_command_t).
//
// Operator commands: confirm, reject, move/resize (a new box in the map frame), add (a region drawn
// on a keyframe, already lifted to a 3D box by the robot). Each command id is applied once: a
// command sent again (the ground station resends until it hears the acknowledgement) gets the same
// outcome without being applied twice. Rejected regions stay in the list (the operator sees what was
// rejected) and suppress new detections whose box overlaps theirs; an operator's box is no longer
// changed by detections.
//
// Frames: `map` is the frame the robot publishes in (the run's world, or the prior map's once the
// robot relocalized against it: hwr-robot's T_out_world). Entries keep their box in the map frame
// (persisted, published) and, once placed, in the run's world frame too (T_world_box, not
// persisted): entries loaded from an earlier run are placed when the map frame is known in this run
// (place(): after relocalization). Only placed entries suppress detections.
//
// Persistence: save() writes the whole ledger as YAML (entries, the next id, and every command with
// its outcome: the operator journal) atomically; load() reads it back strictly (a malformed file is
// an error naming the line, never a partial ledger). The robot keeps it in its map store
// (DIR/detections.yaml) and loads the prior map's on its next visit, so the operator's decisions
// survive a restart of the robot.
//
// Memory: entries and commands are reserved at construction (grows beyond only past the reserve:
// operator-paced events). Not thread-safe: the mapping task owns it.

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <opencv2/core/types.hpp>

#include "hwr/core/status.hpp"
#include "hwr/detect/detection.hpp"

namespace hwr::detect {

// The numbers of mapio's detection_t.state and operator_command_t.kind.
enum class DetectionState : uint8_t { kProposed = 0, kConfirmed = 1, kRejected = 2 };
enum class OperatorCommandKind : uint8_t { kConfirm = 0, kReject = 1, kMove = 2, kAdd = 3 };

const char* detection_state_name(DetectionState state);       // "proposed", "confirmed", "rejected"
const char* operator_command_name(OperatorCommandKind kind);  // "confirm", "reject", "move", "add"

struct LedgerEntry {
  int64_t id = -1;  // stable across runs of one map (the ledger numbers them)
  DetectionSource source = DetectionSource::kGeometry;
  SeamKind kind = SeamKind::kFillet;
  DetectionState state = DetectionState::kProposed;
  float confidence = 0.0f;
  int64_t keyframe_t_ns = 0;  // the keyframe it was (last) anchored on or drawn on
  cv::Rect2f box_px;          // on that keyframe
  Eigen::Isometry3d T_map_box = Eigen::Isometry3d::Identity();
  Eigen::Vector3d half_size_m = Eigen::Vector3d::Zero();
  bool operator_box = false;  // moved, resized or drawn by the operator: detections no longer change it
  // The seam inside the box, fused over the keyframes that saw it (seam_fusion.hpp), map frame; none
  // for a region drawn by the operator or seen only once.
  bool has_seam = false;
  std::array<Eigen::Vector3d, 2> seam_map{Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()};
  // Last change: the robot's clock, but always after every earlier change of the list, also one saved
  // by an earlier run (a replayed or rebooted robot's clock starts again): the ground station keeps
  // the version with the largest time.
  int64_t updated_t_ns = 0;
  // Runtime, not persisted: the box and seam in this run's world frame once placed; this run's
  // fine-map region (-1: none, e.g. rejected or not placed yet).
  bool placed = false;
  Eigen::Isometry3d T_world_box = Eigen::Isometry3d::Identity();
  std::array<Eigen::Vector3d, 2> seam_world{Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()};
  int64_t region_id = -1;
};

struct OperatorCommand {
  int64_t command_id = -1;
  OperatorCommandKind kind = OperatorCommandKind::kConfirm;
  int64_t detection_id = -1;  // confirm, reject, move
  int64_t keyframe_t_ns = 0;  // add: the keyframe it was drawn on
  cv::Rect2f box_px;          // add
  // move: the new box; add: the drawn rectangle lifted to 3D by the robot. Map frame.
  Eigen::Isometry3d T_map_box = Eigen::Isometry3d::Identity();
  Eigen::Vector3d half_size_m = Eigen::Vector3d::Zero();
};

struct CommandOutcome {
  int64_t command_id = -1;
  OperatorCommandKind kind = OperatorCommandKind::kConfirm;
  bool accepted = false;
  std::string reason;         // why refused
  int64_t detection_id = -1;  // the entry changed or created
  int64_t t_ns = 0;           // when applied (robot clock)
};

struct LedgerConfig {
  int reserve_entries = 256;
  int reserve_commands = 256;
};

class DetectionLedger {
 public:
  explicit DetectionLedger(const LedgerConfig& config = {});

  // Reads a ledger saved by save(). kNotFound when the file is absent; kParseError for text that is
  // not YAML, kInvalidArgument for a missing key, a wrong type or a value out of range (a state, a
  // box), each naming the line and key.
  static core::Expected<DetectionLedger> load(const std::string& path, const LedgerConfig& config = {});
  core::Status save(const std::string& path) const;  // atomic (core::write_file_atomic)
  std::string to_yaml() const;

  // A detector's region of this run (id `region_id` in the fine map), with its current box (and seam,
  // when seen.has_seam) in the run's world frame (seen.T_world_box, seen.seam_world): creates its
  // entry or updates it (the box not when it is the operator's). Returns the entry's id.
  int64_t observe_region(int64_t region_id, const LedgerEntry& seen, const Eigen::Isometry3d& T_map_world,
                         int64_t now_ns);
  // Whether a detection with this box (run's world frame) falls on a rejected region: its centre in
  // a placed rejected entry's box, or that entry's centre in its box.
  bool suppressed(const Eigen::Isometry3d& T_world_box, const Eigen::Vector3d& half_size_m) const;
  // Places the entries not placed yet in this run's world (T_world_box = T_map_world^-1 T_map_box)
  // and re-expresses the placed ones in the map frame with T_map_world (it changes when the robot
  // relocalizes). Appends the newly placed entries' ids to *newly_placed (may be null).
  void place(const Eigen::Isometry3d& T_map_world, std::vector<int64_t>* newly_placed, int64_t now_ns);

  // Applies an operator command (see the header comment). A command id seen before returns its first
  // outcome again (repeated = true). An added region's box is in the frame the robot publishes in now
  // (T_map_world): it is placed at once. Refused (accepted = false, reason set): an unknown detection id,
  // a move / add without a valid box (positive finite half sizes, rigid pose), an add without a
  // box_px of positive size, a negative command id. The robot mirrors an accepted command on its fine
  // map (remove, set_fixed_box, add_fixed) and links the new region with link_region().
  CommandOutcome apply(const OperatorCommand& command, const Eigen::Isometry3d& T_map_world, int64_t now_ns,
                       bool* repeated = nullptr);
  void link_region(int64_t entry_id, int64_t region_id);
  // Removes an entry (a duplicate, found before relocalizing, of a region the prior map's list holds:
  // the robot merges the two) and returns it marked rejected and stamped now, for the ground
  // station's copy; false when absent.
  bool drop(int64_t id, int64_t now_ns, LedgerEntry* dropped);

  const std::vector<LedgerEntry>& entries() const { return entries_; }
  const std::vector<CommandOutcome>& commands() const { return commands_; }
  const LedgerEntry* find(int64_t id) const;
  const LedgerEntry* find_region(int64_t region_id) const;
  int64_t next_id() const { return next_id_; }
  // Ids changed since the last call (created, moved, state changed), oldest first; the list is
  // cleared. What the robot publishes.
  void take_changed(std::vector<int64_t>* ids);
  // Marks every entry changed (publish the whole list, e.g. at start-up).
  void mark_all_changed();

 private:
  LedgerEntry* find_mutable(int64_t id);
  void changed(int64_t id);
  int64_t stamp(int64_t now_ns);  // max(now_ns, the last stamp + 1)

  LedgerConfig config_;
  std::vector<LedgerEntry> entries_;
  std::vector<CommandOutcome> commands_;
  std::vector<int64_t> changed_;
  int64_t next_id_ = 0;
  int64_t last_stamp_ns_ = 0;
};

}  // namespace hwr::detect
