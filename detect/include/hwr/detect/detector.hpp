#pragma once
// The detector interface (issue #7 item 1): a keyframe in, welding regions out. Every backend (the
// geometric seam detector, the learned ONNX / TensorRT detector, the operator's regions) implements
// it, so the robot and the bench treat them alike.

#include "hwr/core/status.hpp"
#include "hwr/detect/detection.hpp"
#include "hwr/hal/pinhole_camera.hpp"

#include <opencv2/core/mat.hpp>

namespace hwr::detect {

// One keyframe as the detectors see it. The images are the keyframe store's (not copied).
struct KeyframeView {
  int32_t keyframe_id = -1;
  int64_t t_ns = 0;
  hal::PinholeIntrinsics K;
  const cv::Mat* bgr = nullptr;      // CV_8UC3; may be null (a depth-only detector ignores it)
  const cv::Mat* depth_m = nullptr;  // CV_32FC1, metres, K's size; 0, NaN, inf, < 0: no depth there
  Eigen::Isometry3d T_world_cam = Eigen::Isometry3d::Identity();  // world z up
};

class Detector {
 public:
  virtual ~Detector() = default;
  virtual DetectionSource source() const = 0;
  // Clears *out and appends this keyframe's detections, world members filled (place_in_world).
  // Errors (kInvalidArgument): a missing or wrongly typed image the backend needs, an image not of
  // K's size, invalid K. Bad pixels are never an error.
  virtual core::Status detect(const KeyframeView& view, DetectionList* out) = 0;
};

}  // namespace hwr::detect
