#include "hwr/detect/detection_ledger.hpp"

#include <algorithm>
#include <cinttypes>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <utility>

#include "hwr/core/config.hpp"
#include "hwr/core/file_io.hpp"
#include "hwr/core/se3.hpp"

namespace hwr::detect {
namespace {

constexpr int kFormat = 1;

bool inside_box(const Eigen::Isometry3d& T_world_box, const Eigen::Vector3d& half,
                const Eigen::Vector3d& p_world) {
  const Eigen::Vector3d p = T_world_box.inverse(Eigen::Isometry) * p_world;
  return std::fabs(p.x()) <= half.x() && std::fabs(p.y()) <= half.y() && std::fabs(p.z()) <= half.z();
}

bool valid_box(const Eigen::Isometry3d& T, const Eigen::Vector3d& half) {
  return half.allFinite() && half.minCoeff() > 0 && core::rigid_transform_problem(T).empty();
}

// YAML double-quoted scalar.
std::string quoted(const std::string& s) {
  std::string q = "\"";
  for (const char c : s) {
    if (c == '"' || c == '\\') {
      q += '\\';
      q += c;
    } else if (static_cast<unsigned char>(c) < 0x20) {
      char buf[8];
      std::snprintf(buf, sizeof(buf), "\\x%02x", static_cast<unsigned char>(c));
      q += buf;
    } else {
      q += c;
    }
  }
  return q + "\"";
}

template <class Enum, size_t N>
bool enum_from_name(const std::string& name, const std::array<Enum, N>& values, const char* (*to_name)(Enum),
                    Enum* out) {
  for (const Enum v : values) {
    if (name == to_name(v)) {
      *out = v;
      return true;
    }
  }
  return false;
}

constexpr std::array<DetectionSource, 3> kSources{DetectionSource::kModel, DetectionSource::kGeometry,
                                                  DetectionSource::kOperator};
constexpr std::array<SeamKind, 2> kKinds{SeamKind::kFillet, SeamKind::kButt};
constexpr std::array<DetectionState, 3> kStates{DetectionState::kProposed, DetectionState::kConfirmed,
                                                DetectionState::kRejected};
constexpr std::array<OperatorCommandKind, 4> kCommands{OperatorCommandKind::kConfirm,
                                                       OperatorCommandKind::kReject,
                                                       OperatorCommandKind::kMove, OperatorCommandKind::kAdd};

}  // namespace

const char* detection_state_name(DetectionState state) {
  switch (state) {
    case DetectionState::kProposed:
      return "proposed";
    case DetectionState::kConfirmed:
      return "confirmed";
    case DetectionState::kRejected:
      return "rejected";
  }
  return "unknown";
}

const char* operator_command_name(OperatorCommandKind kind) {
  switch (kind) {
    case OperatorCommandKind::kConfirm:
      return "confirm";
    case OperatorCommandKind::kReject:
      return "reject";
    case OperatorCommandKind::kMove:
      return "move";
    case OperatorCommandKind::kAdd:
      return "add";
  }
  return "unknown";
}

DetectionLedger::DetectionLedger(const LedgerConfig& config) : config_(config) {
  entries_.reserve(static_cast<size_t>(std::max(config.reserve_entries, 0)));
  commands_.reserve(static_cast<size_t>(std::max(config.reserve_commands, 0)));
  changed_.reserve(static_cast<size_t>(std::max(config.reserve_entries, 0)));
}

LedgerEntry* DetectionLedger::find_mutable(int64_t id) {
  for (LedgerEntry& e : entries_)
    if (e.id == id) return &e;
  return nullptr;
}

const LedgerEntry* DetectionLedger::find(int64_t id) const {
  for (const LedgerEntry& e : entries_)
    if (e.id == id) return &e;
  return nullptr;
}

const LedgerEntry* DetectionLedger::find_region(int64_t region_id) const {
  if (region_id < 0) return nullptr;
  for (const LedgerEntry& e : entries_)
    if (e.region_id == region_id) return &e;
  return nullptr;
}

void DetectionLedger::changed(int64_t id) {
  if (std::find(changed_.begin(), changed_.end(), id) == changed_.end()) changed_.push_back(id);
}

int64_t DetectionLedger::stamp(int64_t now_ns) {
  last_stamp_ns_ = std::max(now_ns, last_stamp_ns_ + 1);
  return last_stamp_ns_;
}

void DetectionLedger::take_changed(std::vector<int64_t>* ids) {
  ids->assign(changed_.begin(), changed_.end());
  changed_.clear();
}

void DetectionLedger::mark_all_changed() {
  for (const LedgerEntry& e : entries_) changed(e.id);
}

int64_t DetectionLedger::observe_region(int64_t region_id, const LedgerEntry& seen,
                                        const Eigen::Isometry3d& T_map_world, int64_t now_ns) {
  LedgerEntry* e = nullptr;
  for (LedgerEntry& x : entries_)
    if (x.region_id == region_id) e = &x;
  if (e == nullptr) {
    entries_.push_back(seen);
    e = &entries_.back();
    e->id = next_id_++;
    e->region_id = region_id;
    e->state = DetectionState::kProposed;
    e->operator_box = false;
  } else {
    // Moved by less than a millimetre, the same keyframe, the same seam: nothing to publish.
    const bool same_box =
        e->operator_box || ((e->T_world_box.translation() - seen.T_world_box.translation()).norm() < 1e-3 &&
                            (e->half_size_m - seen.half_size_m).cwiseAbs().maxCoeff() < 1e-3 &&
                            e->keyframe_t_ns == seen.keyframe_t_ns);
    const bool same_seam =
        !seen.has_seam || (e->has_seam && (e->seam_world[0] - seen.seam_world[0]).norm() < 1e-3 &&
                           (e->seam_world[1] - seen.seam_world[1]).norm() < 1e-3);
    if (same_box && same_seam) return e->id;
    if (!e->operator_box) {
      e->confidence = seen.confidence;
      e->keyframe_t_ns = seen.keyframe_t_ns;
      e->box_px = seen.box_px;
      e->half_size_m = seen.half_size_m;
      e->T_world_box = seen.T_world_box;
    }
    if (seen.has_seam) {  // a restored entry keeps its seam until this run has fused one
      e->has_seam = true;
      e->seam_world = seen.seam_world;
    }
  }
  e->placed = true;
  e->T_map_box = T_map_world * e->T_world_box;
  for (int k = 0; k < 2; ++k) e->seam_map[k] = T_map_world * e->seam_world[k];
  e->updated_t_ns = stamp(now_ns);
  changed(e->id);
  return e->id;
}

bool DetectionLedger::suppressed(const Eigen::Isometry3d& T_world_box,
                                 const Eigen::Vector3d& half_size_m) const {
  for (const LedgerEntry& e : entries_) {
    if (!e.placed || e.state != DetectionState::kRejected) continue;
    if (inside_box(e.T_world_box, e.half_size_m, T_world_box.translation()) ||
        inside_box(T_world_box, half_size_m, e.T_world_box.translation()))
      return true;
  }
  return false;
}

void DetectionLedger::place(const Eigen::Isometry3d& T_map_world, std::vector<int64_t>* newly_placed,
                            int64_t now_ns) {
  const Eigen::Isometry3d T_world_map = T_map_world.inverse(Eigen::Isometry);
  for (LedgerEntry& e : entries_) {
    if (!e.placed) {
      e.T_world_box = T_world_map * e.T_map_box;
      for (int k = 0; k < 2; ++k) e.seam_world[k] = T_world_map * e.seam_map[k];
      e.placed = true;
      if (newly_placed != nullptr) newly_placed->push_back(e.id);
      continue;
    }
    const Eigen::Isometry3d T_map_box = T_map_world * e.T_world_box;
    if ((T_map_box.translation() - e.T_map_box.translation()).norm() < 1e-3 &&
        (T_map_box.linear() - e.T_map_box.linear()).cwiseAbs().maxCoeff() < 1e-4)
      continue;
    e.T_map_box = T_map_box;
    for (int k = 0; k < 2; ++k) e.seam_map[k] = T_map_world * e.seam_world[k];
    e.updated_t_ns = stamp(now_ns);
    changed(e.id);
  }
}

bool DetectionLedger::drop(int64_t id, int64_t now_ns, LedgerEntry* dropped) {
  const auto it =
      std::find_if(entries_.begin(), entries_.end(), [id](const LedgerEntry& e) { return e.id == id; });
  if (it == entries_.end()) return false;
  *dropped = *it;
  dropped->state = DetectionState::kRejected;
  dropped->updated_t_ns = stamp(now_ns);
  entries_.erase(it);
  changed_.erase(std::remove(changed_.begin(), changed_.end(), id), changed_.end());
  return true;
}

void DetectionLedger::link_region(int64_t entry_id, int64_t region_id) {
  if (LedgerEntry* e = find_mutable(entry_id)) e->region_id = region_id;
}

CommandOutcome DetectionLedger::apply(const OperatorCommand& c, const Eigen::Isometry3d& T_map_world,
                                      int64_t now_ns, bool* repeated) {
  if (repeated != nullptr) *repeated = false;
  for (const CommandOutcome& o : commands_) {
    if (o.command_id == c.command_id && c.command_id >= 0) {
      if (repeated != nullptr) *repeated = true;
      return o;
    }
  }
  CommandOutcome out;
  out.command_id = c.command_id;
  out.kind = c.kind;
  out.t_ns = now_ns;
  auto refuse = [&](std::string why) {
    out.accepted = false;
    out.reason = std::move(why);
    if (c.command_id >= 0) commands_.push_back(out);
    return out;
  };
  if (c.command_id < 0) return refuse("negative command id");
  const Eigen::Isometry3d T_world_map = T_map_world.inverse(Eigen::Isometry);
  if (c.kind == OperatorCommandKind::kAdd) {
    if (!(c.box_px.width > 0 && c.box_px.height > 0)) return refuse("add: the drawn rectangle has no area");
    if (!valid_box(c.T_map_box, c.half_size_m))
      return refuse(
          "add: no 3D box (no world box given, and the keyframe's depth is no longer kept or too sparse "
          "inside the rectangle)");
    LedgerEntry e;
    e.id = next_id_++;
    e.source = DetectionSource::kOperator;
    e.state = DetectionState::kConfirmed;  // the operator drew it: nothing left to confirm
    e.confidence = 1.0f;
    e.keyframe_t_ns = c.keyframe_t_ns;
    e.box_px = c.box_px;
    e.T_map_box = c.T_map_box;
    e.half_size_m = c.half_size_m;
    e.operator_box = true;
    e.updated_t_ns = stamp(now_ns);
    // Drawn on what the ground shows now: a box in the frame the robot publishes in now, whether or
    // not that is the prior map's yet.
    e.placed = true;
    e.T_world_box = T_world_map * e.T_map_box;
    entries_.push_back(e);
    changed(e.id);
    out.accepted = true;
    out.detection_id = e.id;
    commands_.push_back(out);
    return out;
  }
  LedgerEntry* e = find_mutable(c.detection_id);
  if (e == nullptr) return refuse("no detection " + std::to_string(c.detection_id));
  out.detection_id = e->id;
  switch (c.kind) {
    case OperatorCommandKind::kConfirm:
      e->state = DetectionState::kConfirmed;
      break;
    case OperatorCommandKind::kReject:
      e->state = DetectionState::kRejected;
      break;
    case OperatorCommandKind::kMove:
      if (!valid_box(c.T_map_box, c.half_size_m))
        return refuse("move: the box needs positive finite sizes and a unit quaternion");
      e->T_map_box = c.T_map_box;
      e->half_size_m = c.half_size_m;
      e->operator_box = true;
      if (e->placed) e->T_world_box = T_world_map * e->T_map_box;
      break;
    case OperatorCommandKind::kAdd:
      break;  // handled above
  }
  e->updated_t_ns = stamp(now_ns);
  changed(e->id);
  out.accepted = true;
  commands_.push_back(out);
  return out;
}

std::string DetectionLedger::to_yaml() const {
  std::string y;
  char buf[512];
  std::snprintf(buf, sizeof(buf),
                "# hwr-robot's welding regions and the operator's commands (detect/detection_ledger.hpp)\n"
                "format: %d\nnext_id: %" PRId64 "\nentries:%s\n",
                kFormat, next_id_, entries_.empty() ? " []" : "");
  y += buf;
  for (const LedgerEntry& e : entries_) {
    const Eigen::Vector3d t = e.T_map_box.translation();
    const Eigen::Quaterniond q(e.T_map_box.linear());
    std::snprintf(buf, sizeof(buf),
                  "  - id: %" PRId64
                  "\n    source: %s\n    kind: %s\n    state: %s\n    confidence: %.9g\n"
                  "    keyframe_t_ns: %" PRId64 "\n    box_px: [%.9g, %.9g, %.9g, %.9g]\n",
                  e.id, detection_source_name(e.source), seam_kind_name(e.kind),
                  detection_state_name(e.state), e.confidence, e.keyframe_t_ns, e.box_px.x, e.box_px.y,
                  e.box_px.width, e.box_px.height);
    y += buf;
    std::snprintf(buf, sizeof(buf),
                  "    t_map_box_m: [%.17g, %.17g, %.17g]\n    q_map_box: [%.17g, %.17g, %.17g, %.17g]\n"
                  "    half_size_m: [%.17g, %.17g, %.17g]\n    operator_box: %s\n    updated_t_ns: %" PRId64
                  "\n",
                  t.x(), t.y(), t.z(), q.w(), q.x(), q.y(), q.z(), e.half_size_m.x(), e.half_size_m.y(),
                  e.half_size_m.z(), e.operator_box ? "true" : "false", e.updated_t_ns);
    y += buf;
    if (e.has_seam) {
      std::snprintf(buf, sizeof(buf), "    seam_map_m: [%.17g, %.17g, %.17g, %.17g, %.17g, %.17g]\n",
                    e.seam_map[0].x(), e.seam_map[0].y(), e.seam_map[0].z(), e.seam_map[1].x(),
                    e.seam_map[1].y(), e.seam_map[1].z());
      y += buf;
    }
  }
  y += commands_.empty() ? "commands: []\n" : "commands:\n";
  for (const CommandOutcome& o : commands_) {
    std::snprintf(buf, sizeof(buf),
                  "  - command_id: %" PRId64 "\n    kind: %s\n    accepted: %s\n    detection_id: %" PRId64
                  "\n    t_ns: %" PRId64 "\n    reason: ",
                  o.command_id, operator_command_name(o.kind), o.accepted ? "true" : "false", o.detection_id,
                  o.t_ns);
    y += buf;
    y += quoted(o.reason) + "\n";
  }
  return y;
}

core::Status DetectionLedger::save(const std::string& path) const {
  return core::write_file_atomic(path, to_yaml());
}

core::Expected<DetectionLedger> DetectionLedger::load(const std::string& path, const LedgerConfig& config) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec))
    return core::NotFound("detection ledger: " + path + ": no such file");
  auto doc = core::ConfigDocument::load_file(path);
  if (!doc.ok()) return doc.status();
  core::ConfigMap root = doc->root();
  int format = 0;
  DetectionLedger ledger(config);
  root.require("format", &format).require("next_id", &ledger.next_id_);
  if (format != kFormat) {
    return core::InvalidArgument("detection ledger: " + path + ": format " + std::to_string(format) +
                                 " is not " + std::to_string(kFormat));
  }
  for (core::ConfigMap& m : root.list("entries")) {
    LedgerEntry e;
    std::string source, kind, state;
    Eigen::Vector4d box_px = Eigen::Vector4d::Zero(), q = Eigen::Vector4d(1, 0, 0, 0);
    Eigen::Vector3d t = Eigen::Vector3d::Zero();
    double confidence = 0;
    m.require("id", &e.id).require("source", &source).require("kind", &kind).require("state", &state);
    m.require("confidence", &confidence)
        .require("keyframe_t_ns", &e.keyframe_t_ns)
        .require("box_px", &box_px);
    m.require("t_map_box_m", &t).require("q_map_box", &q).require("half_size_m", &e.half_size_m);
    m.require("operator_box", &e.operator_box).require("updated_t_ns", &e.updated_t_ns);
    if (m.has("seam_map_m")) {
      std::vector<double> seam;
      m.get("seam_map_m", &seam);
      if (seam.size() != 6) {
        m.record_error("seam_map_m", "expected 6 numbers (the seam's two ends)");
      } else {
        e.has_seam = true;
        e.seam_map[0] = Eigen::Vector3d(seam[0], seam[1], seam[2]);
        e.seam_map[1] = Eigen::Vector3d(seam[3], seam[4], seam[5]);
        if (!(e.seam_map[0].allFinite() && e.seam_map[1].allFinite()))
          m.record_error("seam_map_m", "not finite");
      }
    }
    if (!enum_from_name(source, kSources, detection_source_name, &e.source))
      m.record_error("source", "expected model, geometry or operator, got '" + source + "'");
    if (!enum_from_name(kind, kKinds, seam_kind_name, &e.kind))
      m.record_error("kind", "expected fillet or butt, got '" + kind + "'");
    if (!enum_from_name(state, kStates, detection_state_name, &e.state))
      m.record_error("state", "expected proposed, confirmed or rejected, got '" + state + "'");
    if (!(std::fabs(q.norm() - 1.0) < 1e-6)) m.record_error("q_map_box", "not a unit quaternion");
    if (!(e.half_size_m.allFinite() && e.half_size_m.minCoeff() > 0))
      m.record_error("half_size_m", "expected three positive sizes");
    if (!(confidence >= 0 && confidence <= 1)) m.record_error("confidence", "expected a value in [0, 1]");
    if (e.id < 0 || e.id >= ledger.next_id_) m.record_error("id", "expected 0 <= id < next_id");
    if (ledger.find(e.id) != nullptr) m.record_error("id", "listed twice");
    e.confidence = static_cast<float>(confidence);
    e.box_px = cv::Rect2f(static_cast<float>(box_px[0]), static_cast<float>(box_px[1]),
                          static_cast<float>(box_px[2]), static_cast<float>(box_px[3]));
    e.T_map_box.linear() = Eigen::Quaterniond(q[0], q[1], q[2], q[3]).normalized().toRotationMatrix();
    e.T_map_box.translation() = t;
    ledger.last_stamp_ns_ = std::max(ledger.last_stamp_ns_, e.updated_t_ns);
    ledger.entries_.push_back(e);
  }
  for (core::ConfigMap& m : root.list("commands")) {
    CommandOutcome o;
    std::string kind;
    m.require("command_id", &o.command_id).require("kind", &kind).require("accepted", &o.accepted);
    m.require("detection_id", &o.detection_id).require("t_ns", &o.t_ns).require("reason", &o.reason);
    if (!enum_from_name(kind, kCommands, operator_command_name, &o.kind))
      m.record_error("kind", "expected confirm, reject, move or add, got '" + kind + "'");
    ledger.commands_.push_back(o);
  }
  HWR_RETURN_IF_ERROR(doc->finish());
  return ledger;
}

}  // namespace hwr::detect
