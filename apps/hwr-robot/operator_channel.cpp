#include "operator_channel.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

#include "hwr/core/log.hpp"

namespace hwr::robot {
namespace {

// The whole list goes out again this often: a ground station that (re)started meanwhile catches up.
constexpr int64_t kRepublishNs = 5'000'000'000;
// The newest keyframe's image goes to the ground station at most this often.
constexpr int64_t kKeyframeImagePeriodNs = 2'000'000'000;

// The image rectangle of a box (T_cam_box, half sizes) on its keyframe: its corners in front of the
// camera projected, clipped to the image. Empty when no corner is in front.
cv::Rect2f box_rect_px(const Eigen::Isometry3d& T_cam_box, const Eigen::Vector3d& half,
                       const hal::PinholeIntrinsics& K) {
  float u0 = std::numeric_limits<float>::max(), v0 = u0, u1 = -u0, v1 = -u0;
  for (int i = 0; i < 8; ++i) {
    const Eigen::Vector3d c =
        T_cam_box * Eigen::Vector3d((i & 4) ? half.x() : -half.x(), (i & 2) ? half.y() : -half.y(),
                                    (i & 1) ? half.z() : -half.z());
    if (c.z() < 1e-3) continue;
    const float u = static_cast<float>(K.fx * c.x() / c.z() + K.cx);
    const float v = static_cast<float>(K.fy * c.y() / c.z() + K.cy);
    u0 = std::min(u0, u), u1 = std::max(u1, u), v0 = std::min(v0, v), v1 = std::max(v1, v);
  }
  if (u0 > u1) return {};
  const float w = static_cast<float>(K.width), h = static_cast<float>(K.height);
  u0 = std::clamp(u0, 0.0f, w), u1 = std::clamp(u1, 0.0f, w);
  v0 = std::clamp(v0, 0.0f, h), v1 = std::clamp(v1, 0.0f, h);
  return {u0, v0, u1 - u0, v1 - v0};
}

Eigen::Isometry3d box_pose(const double* centre, const double* q_wxyz) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::Quaterniond(q_wxyz[0], q_wxyz[1], q_wxyz[2], q_wxyz[3]).normalized().toRotationMatrix();
  T.translation() = Eigen::Vector3d(centre[0], centre[1], centre[2]);
  return T;
}

}  // namespace

OperatorChannel::OperatorChannel(detect::DetectionLedger ledger, const hal::PinholeIntrinsics& K,
                                 mapio::MapStreamer* streamer, std::string save_path)
    : ledger_(std::move(ledger)), K_(K), streamer_(streamer), save_path_(std::move(save_path)) {
  auto lifter = detect::BoxLifter::create(detect::BoxLiftConfig{}, K);
  if (lifter.ok()) lifter_.emplace(std::move(lifter.value()));
  ids_.reserve(256);
  ledger_.mark_all_changed();  // the list as it starts (the prior map's) goes out first
}

bool OperatorChannel::suppress(const Eigen::Isometry3d& T_world_box, const Eigen::Vector3d& half_size_m) {
  if (!ledger_.suppressed(T_world_box, half_size_m)) return false;
  ++counters_.detections_suppressed;
  return true;
}

void OperatorChannel::add_detection(const detect::Detection& detection) {
  fusion_changed_ = fusion_.add(detection) || fusion_changed_;
}

core::Status OperatorChannel::save() {
  if (save_path_.empty()) return core::Status::Ok();
  const core::Status st = ledger_.save(save_path_);
  if (!st.ok()) ++counters_.save_errors;
  return st;
}

void OperatorChannel::step(recon::FineRegionMap* fine, const estimation::KeyframeStore& keyframes,
                           const Eigen::Isometry3d& T_map_world, bool map_frame_known, int64_t now_ns) {
  if (map_frame_known) {
    ids_.clear();
    ledger_.place(T_map_world, &ids_, now_ns);
    restore_placed(fine, ids_, now_ns, /*merge_duplicates=*/true);
  }
  sync_regions(*fine, T_map_world, now_ns);
  if (streamer_ != nullptr) {
    // Every command waiting is applied, the list saved once, then all are acknowledged: an
    // acknowledged command is on disk (it survives a restart of the robot). When the save fails
    // nothing is acknowledged; the ground station resends, and a repeated command saves again.
    acks_.clear();
    bool changed = false;
    while (streamer_->take_operator_command(&command_)) {
      bool repeated = false;
      const detect::CommandOutcome o =
          apply_command(command_, fine, keyframes, T_map_world, now_ns, &repeated);
      changed = changed || !repeated;
      acks_.push_back(o);
    }
    if (!acks_.empty()) {
      if (changed || unsaved_) {
        const core::Status st = save();
        unsaved_ = !st.ok();
        if (unsaved_) {
          HWR_LOG_ERROR("robot",
                        "operator: the detection list was not saved (%s); %zu command(s) not acknowledged",
                        st.message().c_str(), acks_.size());
        }
      }
      if (!unsaved_) {
        for (const detect::CommandOutcome& o : acks_) {
          hwr_lcm::command_ack_t ack;
          ack.t_ns = now_ns;
          ack.command_id = o.command_id;
          ack.accepted = o.accepted ? 1 : 0;
          ack.reason = o.reason;
          ack.detection_id = o.detection_id;
          streamer_->post_command_ack(ack);
        }
      }
    }
  }
  publish(now_ns);
  send_keyframe_images(keyframes, now_ns);
}

// The images of the keyframes the list's entries were seen on, once each while the keyframe store
// still holds them, and the newest keyframe every kKeyframeImagePeriodNs: what the operator checks a
// box against and draws new regions on (docs/ground_viewer.md). Only a keyframe whose images are kept
// can take an added region (lift_drawn), so these are the ones worth drawing on.
void OperatorChannel::send_keyframe_images(const estimation::KeyframeStore& keyframes, int64_t now_ns) {
  if (streamer_ == nullptr || keyframes.empty()) return;
  auto send = [&](int id) {
    const estimation::Keyframe* kf = keyframes.get(id);
    const cv::Mat* bgr = keyframes.bgr(id);
    if (kf == nullptr || bgr == nullptr || bgr->empty() || !images_sent_.insert(kf->t_ns).second) return;
    streamer_->post_keyframe_image(kf->t_ns, *bgr);
    ++counters_.keyframe_images;
  };
  for (int id = keyframes.oldest_id(); id <= keyframes.newest_id(); ++id) {
    const estimation::Keyframe* kf = keyframes.get(id);
    if (kf == nullptr || images_sent_.count(kf->t_ns) > 0) continue;
    for (const detect::LedgerEntry& e : ledger_.entries()) {
      if (e.keyframe_t_ns == kf->t_ns) {
        send(id);
        break;
      }
    }
  }
  if (last_image_ns_ < 0 || now_ns - last_image_ns_ >= kKeyframeImagePeriodNs) {
    last_image_ns_ = now_ns;
    send(keyframes.newest_id());
  }
}

// Entries placed in this run's world become regions of the fine map again (not the rejected ones:
// those only suppress detections), with the box they have: fixed (detections merge into it without
// re-anchoring or growing it). A region this run found before it knew the map frame and that
// overlaps the entry (either box holds the other's centre) is the same weld: when the operator has
// not touched it, the entry takes its region, and its own entry leaves the list (published one last
// time as rejected, so the ground station's copy says it is not to be welded). Only for the prior
// map's entries (merge_duplicates); a region the operator adds, or brings back, is a region of its own.
void OperatorChannel::restore_placed(recon::FineRegionMap* fine, const std::vector<int64_t>& ids,
                                     int64_t now_ns, bool merge_duplicates) {
  for (const int64_t id : ids) {
    const detect::LedgerEntry* e = ledger_.find(id);
    if (e == nullptr || e->state == detect::DetectionState::kRejected || e->region_id >= 0) continue;
    const Eigen::Isometry3d T_world_box = e->T_world_box;
    const Eigen::Vector3d half = e->half_size_m;
    int64_t duplicate = -1, region = -1;
    for (const detect::LedgerEntry& other : ledger_.entries()) {
      if (!merge_duplicates) break;
      if (other.id == id || other.region_id < 0 || other.operator_box ||
          other.state != detect::DetectionState::kProposed)
        continue;
      const bool overlap =
          recon::inside_region_box(other.T_world_box.inverse(Eigen::Isometry) * T_world_box.translation(),
                                   other.half_size_m) ||
          recon::inside_region_box(T_world_box.inverse(Eigen::Isometry) * other.T_world_box.translation(),
                                   half);
      if (!overlap) continue;
      duplicate = other.id;
      region = other.region_id;
      break;
    }
    if (duplicate >= 0) {
      detect::LedgerEntry dropped;
      if (ledger_.drop(duplicate, now_ns, &dropped)) post(dropped);
      fine->set_fixed_box(static_cast<uint32_t>(region), T_world_box, half);
      ++counters_.duplicates_merged;
    } else {
      const detect::LedgerEntry& entry = *ledger_.find(id);
      recon::WeldRegion r;
      r.source = static_cast<recon::WeldRegionSource>(entry.source);
      r.confidence = entry.confidence;
      recon::set_weld_region_label(&r, detect::seam_kind_name(entry.kind));
      r.t_ns = entry.keyframe_t_ns;
      r.half_size_m = half;
      region = fine->add_fixed(r, T_world_box);
      if (region < 0) continue;  // the table is full (counted by the fine map)
    }
    ledger_.link_region(id, region);
    ++counters_.regions_restored;
  }
}

void OperatorChannel::sync_regions(const recon::FineRegionMap& fine, const Eigen::Isometry3d& T_map_world,
                                   int64_t now_ns) {
  if (fusion_changed_) {
    fused_ = fusion_.fused();  // only when a detection came in: keyframe-paced
    fusion_changed_ = false;
  }
  for (int i = 0; i < fine.active_regions(); ++i) {
    const recon::WeldRegion& r = fine.region(i);
    if (r.source == recon::WeldRegionSource::kSimTruth) continue;  // not a detection (--regions truth)
    detect::LedgerEntry seen;
    seen.source = static_cast<detect::DetectionSource>(r.source);
    seen.kind = recon::weld_region_label(r) == "butt" ? detect::SeamKind::kButt : detect::SeamKind::kFillet;
    seen.confidence = r.confidence;
    seen.keyframe_t_ns = r.t_ns;
    if (r.keyframe_id >= 0) seen.box_px = box_rect_px(r.T_cam_region, r.half_size_m, K_);
    seen.T_world_box = fine.T_world_region(i);
    seen.half_size_m = r.half_size_m;
    // The region's seam: the fused seam of its kind seen most often whose midpoint lies in the box.
    const Eigen::Isometry3d T_region_world = seen.T_world_box.inverse(Eigen::Isometry);
    int most = 0;
    for (const detect::FusedSeam& f : fused_) {
      if (f.seam.kind != seen.kind || f.detections <= most ||
          !recon::inside_region_box(T_region_world * (0.5 * (f.seam.a + f.seam.b)), r.half_size_m))
        continue;
      most = f.detections;
      seen.has_seam = true;
      seen.seam_world = {f.seam.a, f.seam.b};
    }
    ledger_.observe_region(r.id, seen, T_map_world, now_ns);
  }
}

bool OperatorChannel::lift_drawn(const estimation::KeyframeStore& keyframes, int64_t keyframe_t_ns,
                                 const cv::Rect2f& box_px, const Eigen::Isometry3d& T_map_world,
                                 Eigen::Isometry3d* T_map_box, Eigen::Vector3d* half_size_m) {
  if (!lifter_ || keyframes.empty()) return false;
  for (int id = keyframes.oldest_id(); id <= keyframes.newest_id(); ++id) {
    const estimation::Keyframe* kf = keyframes.get(id);
    if (kf == nullptr || kf->t_ns != keyframe_t_ns) continue;
    const cv::Mat* depth = keyframes.depth_m(id);
    if (depth == nullptr || depth->empty()) return false;
    detect::Detection d;
    auto lifted = lifter_->lift(*depth, box_px, &d);
    if (!lifted.ok() || lifted.value() != detect::LiftOutcome::kLifted) return false;
    *T_map_box = T_map_world * kf->T_world_cam * d.T_cam_box;
    *half_size_m = d.half_size_m;
    return true;
  }
  return false;
}

detect::CommandOutcome OperatorChannel::apply_command(const hwr_lcm::operator_command_t& msg,
                                                      recon::FineRegionMap* fine,
                                                      const estimation::KeyframeStore& keyframes,
                                                      const Eigen::Isometry3d& T_map_world, int64_t now_ns,
                                                      bool* repeated) {
  detect::OperatorCommand c;
  c.command_id = msg.command_id;
  c.kind = static_cast<detect::OperatorCommandKind>(msg.kind);
  c.detection_id = msg.detection_id;
  c.keyframe_t_ns = msg.keyframe_t_ns;
  c.box_px = cv::Rect2f(msg.box_px[0], msg.box_px[1], msg.box_px[2], msg.box_px[3]);
  c.T_map_box = box_pose(msg.box_center_world_m, msg.box_q_world_box);
  c.half_size_m = 0.5 * Eigen::Vector3d(msg.box_size_m[0], msg.box_size_m[1], msg.box_size_m[2]);
  // add without a world box: the drawn rectangle lifted with the keyframe's depth (a command whose
  // keyframe is no longer kept and that has no world box is refused by the ledger).
  if (c.kind == detect::OperatorCommandKind::kAdd && !(c.half_size_m.minCoeff() > 0))
    lift_drawn(keyframes, c.keyframe_t_ns, c.box_px, T_map_world, &c.T_map_box, &c.half_size_m);
  const detect::CommandOutcome o = ledger_.apply(c, T_map_world, now_ns, repeated);
  if (*repeated) {
    ++counters_.commands_repeated;
  } else if (o.accepted) {
    ++counters_.commands_applied;
    // Mirror it on the map's regions: a rejected region leaves the fine map; a moved one keeps the
    // operator's box; an added one, or a confirmed / moved entry without a region (rejected before),
    // becomes one.
    const detect::LedgerEntry* e = ledger_.find(o.detection_id);
    if (e != nullptr && e->placed) {
      if (c.kind == detect::OperatorCommandKind::kReject) {
        if (e->region_id >= 0) fine->remove(static_cast<uint32_t>(e->region_id));
        ledger_.link_region(e->id, -1);
      } else if (e->region_id >= 0) {
        if (c.kind == detect::OperatorCommandKind::kMove)
          fine->set_fixed_box(static_cast<uint32_t>(e->region_id), e->T_world_box, e->half_size_m);
      } else {
        ids_.assign(1, e->id);
        restore_placed(fine, ids_, now_ns, /*merge_duplicates=*/false);
      }
    }
    HWR_LOG_INFO("robot", "operator command %lld (%s): applied to detection %lld",
                 static_cast<long long>(o.command_id), detect::operator_command_name(o.kind),
                 static_cast<long long>(o.detection_id));
  } else {
    ++counters_.commands_refused;
    HWR_LOG_WARN("robot", "operator command %lld (%s): refused: %s", static_cast<long long>(o.command_id),
                 detect::operator_command_name(o.kind), o.reason.c_str());
  }
  return o;
}

void OperatorChannel::post(const detect::LedgerEntry& e) {
  if (streamer_ == nullptr) return;
  hwr_lcm::detection_t& d = detection_;
  d.t_ns = e.updated_t_ns;
  d.detection_id = e.id;
  d.segment_id = -1;
  d.keyframe_t_ns = e.keyframe_t_ns;
  d.source = static_cast<int8_t>(e.source);
  d.state = static_cast<int8_t>(e.state);
  d.confidence = std::clamp(e.confidence, 0.0f, 1.0f);
  d.box_px[0] = e.box_px.x, d.box_px[1] = e.box_px.y;
  d.box_px[2] = e.box_px.width, d.box_px[3] = e.box_px.height;
  const Eigen::Vector3d t = e.T_map_box.translation();
  const Eigen::Quaterniond q(e.T_map_box.linear());
  for (int k = 0; k < 3; ++k) {
    d.box_center_world_m[k] = t[k];
    d.box_size_m[k] = 2.0 * e.half_size_m[k];
  }
  d.box_q_world_box[0] = q.w(), d.box_q_world_box[1] = q.x();
  d.box_q_world_box[2] = q.y(), d.box_q_world_box[3] = q.z();
  // Operator-paced (a changed entry, the whole list every 5 s): the message is copied into the
  // streamer's queue anyway, so its rows are simply rebuilt.
  d.num_seam_points = e.has_seam ? 2 : 0;
  d.seam_world_m.assign(static_cast<size_t>(d.num_seam_points), std::vector<double>(3, 0.0));
  for (int k = 0; k < d.num_seam_points; ++k)
    for (int c = 0; c < 3; ++c)
      d.seam_world_m[static_cast<size_t>(k)][c] = e.seam_map[static_cast<size_t>(k)][c];
  streamer_->post_detection(d);
  ++counters_.published;
}

void OperatorChannel::publish(int64_t now_ns) {
  if (streamer_ == nullptr) return;
  if (last_full_publish_ns_ < 0 || now_ns - last_full_publish_ns_ >= kRepublishNs) {
    ledger_.mark_all_changed();
    last_full_publish_ns_ = now_ns;
  }
  ledger_.take_changed(&ids_);
  for (const int64_t id : ids_)
    if (const detect::LedgerEntry* e = ledger_.find(id)) post(*e);
}

}  // namespace hwr::robot
