#pragma once
// Replay of an EuRoC MAV sequence in ASL layout (Burri et al., IJRR 2016), given its mav0 folder:
//   cam0/, cam1/       data.csv ("#timestamp [ns],filename"), data/<filename>.png, sensor.yaml
//   imu0/              data.csv (sensor_csv.hpp format), sensor.yaml (optional)
//   state_groundtruth_estimate0/data.csv, or gt0/data.csv (optional; EurocState rows)
// and, optionally, a TUM-format trajectory beside mav0 (groundtruth_ov_data/*_original.txt, the
// Vicon ground truth as OpenVINS ships it), or one named in the options.
//
// Cameras are optional as a pair (IMU-only sequences have neither cam0 nor cam1). Frames listed in
// a camera's data.csv whose PNG is absent are skipped with one warning and counted (the EuRoC
// copies we use list a few such frames); stereo pairs are associated by nearest timestamp.
// sensor.yaml files begin with OpenCV's "%YAML:1.0" directive, which is dropped before parsing;
// only the keys used here are read, others are ignored (third-party input).

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <opencv2/core/mat.hpp>

#include "hwr/core/status.hpp"
#include "hwr/core/tum_trajectory.hpp"
#include "hwr/hal/imu_sample.hpp"
#include "hwr/hal/pinhole_camera.hpp"
#include "hwr/hal/sensor_csv.hpp"

namespace hwr::hal {

struct EurocCameraCalib {
  PinholeIntrinsics intrinsics;  // distortion: radial-tangential k1 k2 p1 p2 (k3 = 0)
  Eigen::Isometry3d T_body_cam = Eigen::Isometry3d::Identity();  // sensor.yaml T_BS
  double rate_hz = 0;
};

struct EurocImuCalib {
  bool present = false;  // false: no imu0/sensor.yaml, fields keep these defaults
  Eigen::Isometry3d T_body_imu = Eigen::Isometry3d::Identity();
  double rate_hz = 0;
  double gyro_noise_density = 0;   // rad/s/sqrt(Hz)
  double gyro_random_walk = 0;     // rad/s^2/sqrt(Hz)
  double accel_noise_density = 0;  // m/s^2/sqrt(Hz)
  double accel_random_walk = 0;    // m/s^3/sqrt(Hz)
};

// cam sensor.yaml: camera_model pinhole, distortion_model radial-tangential, intrinsics
// [fu fv cu cv], resolution [w h], distortion_coefficients (4 or 5), T_BS (4x4, rigid), rate_hz.
core::Expected<EurocCameraCalib> read_euroc_camera_yaml(const std::string& path);
// imu sensor.yaml: T_BS, rate_hz and the four noise parameters.
core::Expected<EurocImuCalib> read_euroc_imu_yaml(const std::string& path);

struct EurocDatasetOptions {
  double max_stereo_dt_s = 0.002;  // cam0/cam1 frames closer than this form a pair
  // TUM trajectory to load into tum_groundtruth(); relative to the folder above mav0. Empty: the
  // single groundtruth_ov_data/*_original.txt there, if exactly one exists.
  std::string tum_groundtruth_file;
};

class EurocDataset {
 public:
  static core::Expected<EurocDataset> open(const std::string& mav0_dir,
                                           const EurocDatasetOptions& options = {});

  bool has_stereo() const { return has_stereo_; }
  // Stereo pairs with both images present, in time order.
  size_t size() const { return pairs_.size(); }
  int64_t frame_time_ns(size_t i) const { return cam_[0].frames[pairs_[i].left].t_ns; }
  int64_t right_time_ns(size_t i) const { return cam_[1].frames[pairs_[i].right].t_ns; }
  const std::string& left_path(size_t i) const { return cam_[0].frames[pairs_[i].left].file; }
  const std::string& right_path(size_t i) const { return cam_[1].frames[pairs_[i].right].file; }

  // Decodes pair i as 8-bit gray images of the calibrated resolution (buffers reused when sizes
  // match). Not thread-safe.
  core::Status load_stereo(size_t i, cv::Mat* left_gray, cv::Mat* right_gray) const;

  const EurocCameraCalib& cam0() const { return cam_[0].calib; }
  const EurocCameraCalib& cam1() const { return cam_[1].calib; }
  // Maps cam1 points into cam0: T_body_cam0^-1 * T_body_cam1.
  Eigen::Isometry3d T_cam0_cam1() const {
    return cam_[0].calib.T_body_cam.inverse() * cam_[1].calib.T_body_cam;
  }
  // Rows of camN/data.csv, and how many of them have no image file (skipped).
  size_t listed_frames(int cam) const { return cam_[cam].listed; }
  size_t missing_images(int cam) const { return cam_[cam].missing; }

  const EurocImuCalib& imu_calib() const { return imu_calib_; }
  const std::vector<ImuSample>& imu() const { return imu_; }
  // Empty when the sequence has no state ground truth.
  const std::vector<EurocState>& state_groundtruth() const { return state_gt_; }
  // Empty when no TUM ground truth file was found.
  const std::vector<core::StampedPose>& tum_groundtruth() const { return tum_gt_; }
  const std::string& tum_groundtruth_path() const { return tum_gt_path_; }
  const std::string& dir() const { return dir_; }

 private:
  struct Frame {
    int64_t t_ns = 0;
    std::string file;
  };
  struct Camera {
    EurocCameraCalib calib;
    std::vector<Frame> frames;  // only those whose image exists
    size_t listed = 0;
    size_t missing = 0;
  };
  struct Pair {
    size_t left = 0;
    size_t right = 0;
  };

  std::string dir_;
  bool has_stereo_ = false;
  Camera cam_[2];
  std::vector<Pair> pairs_;
  EurocImuCalib imu_calib_;
  std::vector<ImuSample> imu_;
  std::vector<EurocState> state_gt_;
  std::vector<core::StampedPose> tum_gt_;
  std::string tum_gt_path_;
  mutable std::vector<unsigned char> file_bytes_;
};

}  // namespace hwr::hal
