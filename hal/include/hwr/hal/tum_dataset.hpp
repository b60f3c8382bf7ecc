#pragma once
// Replay of a TUM RGB-D sequence folder (Sturm et al., IROS 2012), and of our simulator's runs,
// which use the same layout:
//   rgb.txt, depth.txt     "timestamp filename" per line (filename relative to the folder), '#' comments
//   groundtruth.txt        TUM trajectory (optional; core/tum_trajectory.hpp)
//   accelerometer.txt      "timestamp ax ay az" in m/s^2 (optional; fr1/fr2 only)
// Colour and depth are paired like TUM's associate.py: nearest timestamps, each frame used once,
// |t_rgb - t_depth| < max_association_dt_s. Depth PNGs are 16-bit, raw / depth_scale = metres,
// raw 0 = no measurement.
//
//   auto ds = TumDataset::open(dir);                 // Expected<TumDataset>
//   RgbdFrame frame;                                 // reused: buffers reallocate only on size change
//   for (size_t i = 0; i < ds->size(); ++i) HWR_RETURN_IF_ERROR(ds->load_frame(i, &frame));
//
// open() validates the lists and checks every listed image exists; load_frame() reports a
// truncated or corrupt PNG, a depth PNG that is not 16-bit single channel, and size mismatches.

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>

#include "hwr/core/status.hpp"
#include "hwr/core/tum_trajectory.hpp"
#include "hwr/hal/pinhole_camera.hpp"
#include "hwr/hal/rgbd_frame.hpp"

namespace hwr::hal {

// TUM fr3 colour camera (the "ROS default" intrinsics of fr3; images already undistorted).
inline PinholeIntrinsics tum_fr3_intrinsics() {
  PinholeIntrinsics k;
  k.width = 640;
  k.height = 480;
  k.fx = 535.4;
  k.fy = 539.2;
  k.cx = 320.1;
  k.cy = 247.6;
  return k;
}

// The colour camera of a TUM sequence, chosen by the "freiburgN" in its folder name (the
// benchmark's published calibration): fr1 and fr2 images carry lens distortion (OpenCV order),
// fr3 images are already undistorted. Any other name: fr3.
inline PinholeIntrinsics tum_intrinsics_for(const std::string& dir) {
  PinholeIntrinsics k = tum_fr3_intrinsics();
  if (dir.find("freiburg1") != std::string::npos) {
    k.fx = 517.3, k.fy = 516.5, k.cx = 318.6, k.cy = 255.3;
    k.distortion = {0.2624, -0.9531, -0.0054, 0.0026, 1.1633};
  } else if (dir.find("freiburg2") != std::string::npos) {
    k.fx = 520.9, k.fy = 521.0, k.cx = 325.1, k.cy = 249.7;
    k.distortion = {0.2312, -0.7849, -0.0033, -0.0001, 0.9172};
  }
  return k;
}

struct TumDatasetOptions {
  // Images must match intrinsics.width/height when these are > 0.
  PinholeIntrinsics intrinsics = tum_fr3_intrinsics();
  double depth_scale = 5000.0;         // raw depth units per metre (TUM: 5000)
  double max_association_dt_s = 0.02;  // associate.py --max_difference
  bool require_groundtruth = false;    // true: a missing groundtruth.txt is an error
};

struct TumAccelSample {
  int64_t t_ns = 0;
  Eigen::Vector3d accel_mps2 = Eigen::Vector3d::Zero();
};

class TumDataset {
 public:
  static core::Expected<TumDataset> open(const std::string& dir, const TumDatasetOptions& options = {});

  // Associated (rgb, depth) pairs, in time order.
  size_t size() const { return pairs_.size(); }
  // Colour timestamp of pair i (the frame's t_ns).
  int64_t frame_time_ns(size_t i) const { return rgb_[pairs_[i].rgb].t_ns; }
  int64_t depth_time_ns(size_t i) const { return depth_[pairs_[i].depth].t_ns; }
  // Image paths as opened: the folder joined with the listed relative name.
  const std::string& rgb_path(size_t i) const { return rgb_[pairs_[i].rgb].file; }
  const std::string& depth_path(size_t i) const { return depth_[pairs_[i].depth].file; }

  // Decodes pair i into *out: bgr CV_8UC3, depth_m CV_32FC1 (0 = invalid, counted in
  // invalid_depth_px), intrinsics, t_ns = colour time, seq = index of the colour frame in rgb.txt
  // (gaps = colour frames without depth). Not thread-safe (decode buffers are reused).
  core::Status load_frame(size_t i, RgbdFrame* out) const;

  // Listed frames, before association.
  size_t rgb_count() const { return rgb_.size(); }
  size_t depth_count() const { return depth_.size(); }

  const std::string& dir() const { return dir_; }
  const TumDatasetOptions& options() const { return options_; }
  // Empty when the folder has no groundtruth.txt.
  const std::vector<core::StampedPose>& groundtruth() const { return groundtruth_; }
  // Empty when the folder has no accelerometer.txt.
  const std::vector<TumAccelSample>& accelerometer() const { return accelerometer_; }

 private:
  struct Entry {
    int64_t t_ns = 0;
    std::string file;  // full path
  };
  struct Pair {
    size_t rgb = 0;
    size_t depth = 0;
  };

  std::string dir_;
  TumDatasetOptions options_;
  std::vector<Entry> rgb_;
  std::vector<Entry> depth_;
  std::vector<Pair> pairs_;
  std::vector<core::StampedPose> groundtruth_;
  std::vector<TumAccelSample> accelerometer_;
  // Decode scratch, reused so steady-state replay does not allocate.
  mutable std::vector<unsigned char> file_bytes_;
  mutable cv::Mat depth_raw_;
};

}  // namespace hwr::hal
