#pragma once
// hwr-robot's side of the operator channel (issue #7 item 4; docs/detection.md "Operator"): the
// map's welding regions as the robot's detection list (detect/detection_ledger.hpp), published to
// the ground station on HWR_DETECTION, and the operator's commands from HWR_OPERATOR_CMD applied to
// the list and mirrored on the fine region map, answered on HWR_OPERATOR_ACK, and saved in the map
// store (DIR/detections.yaml) before they are acknowledged. The link is the MapStreamer's (its thread
// sends and receives); everything here runs on the mapping task.

#include <cstdint>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "hwr/detect/box_lift.hpp"
#include "hwr/detect/detection_ledger.hpp"
#include "hwr/detect/seam_fusion.hpp"
#include "hwr/estimation/keyframe_store.hpp"
#include "hwr/hal/pinhole_camera.hpp"
#include "hwr/mapio/map_streamer.hpp"
#include "hwr/recon/fine_region_map.hpp"

namespace hwr::robot {

struct OperatorChannelCounters {
  uint64_t commands_applied = 0, commands_refused = 0, commands_repeated = 0;
  uint64_t detections_suppressed = 0;  // detections on a rejected region, not added to the map
  uint64_t regions_restored = 0;       // placed entries made regions of this run (the prior map's list)
  uint64_t duplicates_merged = 0;      // ... of them, found again before relocalizing: merged
  uint64_t save_errors = 0;
  uint64_t published = 0;
  uint64_t keyframe_images = 0;  // keyframe images handed to the link (HWR_KEYFRAME_IMAGE)
};

class OperatorChannel {
 public:
  // `ledger`: the list to start from (the prior map's, or empty). `save_path`: where the list is kept
  // ("" = not kept). `streamer` may be null (no link: the list is only kept).
  OperatorChannel(detect::DetectionLedger ledger, const hal::PinholeIntrinsics& K,
                  mapio::MapStreamer* streamer, std::string save_path);

  // Whether a detection with this box (run's world frame) lies on a rejected region (counted).
  bool suppress(const Eigen::Isometry3d& T_world_box, const Eigen::Vector3d& half_size_m);
  // A detection of a keyframe (world members filled), supporting ones too (Detection::support_only,
  // which the map does not take): its seam joins the fusion (seam_fusion.hpp) that gives each region
  // of the list its seam line.
  void add_detection(const detect::Detection& detection);

  // Mapping task, after the new keyframes' detections went into the fine map. T_map_world: the frame
  // the robot publishes in; map_frame_known: whether this run knows it (false before relocalizing
  // against a prior map, whose list is then not placed yet).
  void step(recon::FineRegionMap* fine, const estimation::KeyframeStore& keyframes,
            const Eigen::Isometry3d& T_map_world, bool map_frame_known, int64_t now_ns);

  core::Status save();
  const detect::DetectionLedger& ledger() const { return ledger_; }
  const OperatorChannelCounters& counters() const { return counters_; }
  const std::string& save_path() const { return save_path_; }

 private:
  void restore_placed(recon::FineRegionMap* fine, const std::vector<int64_t>& ids, int64_t now_ns,
                      bool merge_duplicates);
  void post(const detect::LedgerEntry& entry);  // one entry on HWR_DETECTION
  void sync_regions(const recon::FineRegionMap& fine, const Eigen::Isometry3d& T_map_world, int64_t now_ns);
  detect::CommandOutcome apply_command(const hwr_lcm::operator_command_t& msg, recon::FineRegionMap* fine,
                                       const estimation::KeyframeStore& keyframes,
                                       const Eigen::Isometry3d& T_map_world, int64_t now_ns, bool* repeated);
  // add: the rectangle drawn on a keyframe lifted to a 3D box (map frame) with that keyframe's depth,
  // when its images are still kept. false when they are not, or too few depth pixels lie inside.
  bool lift_drawn(const estimation::KeyframeStore& keyframes, int64_t keyframe_t_ns, const cv::Rect2f& box_px,
                  const Eigen::Isometry3d& T_map_world, Eigen::Isometry3d* T_map_box,
                  Eigen::Vector3d* half_size_m);
  void publish(int64_t now_ns);
  void send_keyframe_images(const estimation::KeyframeStore& keyframes, int64_t now_ns);

  detect::DetectionLedger ledger_;
  hal::PinholeIntrinsics K_;
  std::optional<detect::BoxLifter>
      lifter_;  // absent only for invalid intrinsics (then add needs a world box)
  mapio::MapStreamer* streamer_;
  std::string save_path_;
  OperatorChannelCounters counters_;
  hwr_lcm::operator_command_t command_;
  hwr_lcm::detection_t detection_;
  std::vector<int64_t> ids_;
  std::vector<detect::CommandOutcome> acks_;  // this step's outcomes, acknowledged after the save
  bool unsaved_ = false;                      // the last save failed
  int64_t last_full_publish_ns_ = -1;
  detect::SeamFusion fusion_;
  std::vector<detect::FusedSeam> fused_;  // fusion_.fused() after the last new detection
  bool fusion_changed_ = false;
  std::set<int64_t> images_sent_;  // keyframe t_ns whose image went to the link
  int64_t last_image_ns_ = -1;
};

}  // namespace hwr::robot
