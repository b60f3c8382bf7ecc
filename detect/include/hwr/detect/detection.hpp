#pragma once
// A welding-region detection (issue #7 item 1): what a detector found on one keyframe — the seam
// (a 3D segment), an oriented box around its plates, the box's image rectangle, a confidence and
// who found it. Detectors work in the keyframe's camera frame; place_in_world() then puts the
// detection in the world with the keyframe's pose, camera -> IMU -> world: the pose estimator's
// T_world_cam is already T_world_imu * T_imu_cam (paper sec. II-C). The source numbers are those of
// recon::WeldRegionSource and of mapio's detection_t, so the robot converts without a table.

#include <array>
#include <cstdint>
#include <vector>

#include <Eigen/Geometry>
#include <opencv2/core/types.hpp>

#include "hwr/hal/pinhole_camera.hpp"

namespace hwr::detect {

enum class DetectionSource : uint8_t { kModel = 0, kGeometry = 1, kOperator = 2 };
enum class SeamKind : uint8_t { kFillet = 0, kButt = 1 };

const char* detection_source_name(DetectionSource source);  // "model", "geometry", "operator"
const char* seam_kind_name(SeamKind kind);                  // "fillet", "butt"

struct Detection {
  DetectionSource source = DetectionSource::kGeometry;
  SeamKind kind = SeamKind::kFillet;
  float confidence = 0.0f;  // [0, 1]
  // Evidence below the detector's own bar (butt_finder.hpp: support_z <= z < min_z): not a welding
  // region by itself, it only supports a seam that a confident detection of another keyframe found
  // (seam_fusion.hpp; hysteresis, as Canny's weak edges join only where a strong one leads).
  bool support_only = false;
  int32_t keyframe_id = -1;
  int64_t t_ns = 0;
  cv::Rect2f box_px;  // the 3D box's corners projected, clipped to the image
  // The seam from start to end, camera and world frame (metres); whether each end is a plate's end
  // seen in the image (false: cut by the image border or a hole, the true end lies beyond).
  std::array<Eigen::Vector3d, 2> seam_cam{Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()};
  std::array<Eigen::Vector3d, 2> seam_world{Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()};
  std::array<bool, 2> end_observed{false, false};
  // Box around the plates: x along the seam, z the base plate's normal (towards the camera side),
  // centred on the plates; T_cam_box has recon::WeldRegion::T_cam_region's meaning.
  Eigen::Isometry3d T_cam_box = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d T_world_box = Eigen::Isometry3d::Identity();
  Eigen::Vector3d half_size_m = Eigen::Vector3d::Zero();
  // The plate faces (fillet: base, web), camera frame: unit normals towards the camera.
  std::array<Eigen::Vector3d, 2> plate_normal_cam{Eigen::Vector3d::UnitZ(), Eigen::Vector3d::UnitZ()};
  double length_m() const { return (seam_cam[1] - seam_cam[0]).norm(); }
};

// Fills the *_world members from the camera-frame ones: seam_world = T_world_cam * seam_cam,
// T_world_box = T_world_cam * T_cam_box.
void place_in_world(const Eigen::Isometry3d& T_world_cam, Detection* d);

// The image rectangle of a box (T_cam_box, half sizes): its corners in front of the camera projected,
// clipped to the image; empty when no corner is in front.
cv::Rect2f box_image_rect(const hal::PinholeIntrinsics& K, const Eigen::Isometry3d& T_cam_box,
                          const Eigen::Vector3d& half_size_m);

// A fixed-capacity list of detections (capacity reserved at construction; push never allocates).
class DetectionList {
 public:
  explicit DetectionList(int capacity);
  void clear() { items_.clear(); }
  bool push(const Detection& d);  // false when full
  int size() const { return static_cast<int>(items_.size()); }
  int capacity() const { return capacity_; }
  bool empty() const { return items_.empty(); }
  const Detection& operator[](int i) const { return items_[static_cast<size_t>(i)]; }
  Detection& operator[](int i) { return items_[static_cast<size_t>(i)]; }
  // Keeps the `keep` most confident (stable among equals).
  void keep_most_confident(int keep);

 private:
  int capacity_ = 0;
  std::vector<Detection> items_;
};

}  // namespace hwr::detect
