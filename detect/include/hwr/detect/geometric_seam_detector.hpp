#pragma once
// The geometric seam detector (issue #7 item 2): welding seams from the keyframe's depth alone, no
// trained weights. The depth image is back-projected on a grid (organized_cloud.hpp), segmented into
// planes (plane_segmentation.hpp), and fillet joints are found among the planes (fillet_finder.hpp).
// Detections of one seam found twice (a plate split into two planes) are merged, the most confident
// max_detections kept, and each is placed in the world with the keyframe's pose. Butt joints (two
// plates side by side, a 2-3 mm gap) are not found yet: the gap is below one pixel and the depth
// noise (docs/detection.md). Sized at create(); detect() allocates nothing.

#include <memory>

#include "hwr/detect/detector.hpp"
#include "hwr/detect/fillet_finder.hpp"
#include "hwr/detect/organized_cloud.hpp"
#include "hwr/detect/plane_segmentation.hpp"

namespace hwr::detect {

struct GeometricSeamConfig {
  DepthNoiseModel noise;
  OrganizedCloudConfig cloud;
  PlaneSegmentationConfig planes;
  FilletConfig fillet;
  int max_detections = 16;
  // Two detections are one seam when their lines are within these (the less confident is dropped).
  double duplicate_angle_rad = 0.175;
  double duplicate_distance_m = 0.03;
};

struct GeometricSeamStats {
  int valid_points = 0, planes = 0, candidates = 0, duplicates = 0;
};

class GeometricSeamDetector final : public Detector {
 public:
  // Errors (kInvalidArgument): invalid K, a config value out of range (the parts' create()).
  static core::Expected<std::unique_ptr<GeometricSeamDetector>> create(const GeometricSeamConfig& config,
                                                                       const hal::PinholeIntrinsics& K);

  DetectionSource source() const override { return DetectionSource::kGeometry; }
  // Needs view.depth_m (CV_32FC1 of K's size); view.bgr is not used.
  core::Status detect(const KeyframeView& view, DetectionList* out) override;
  const GeometricSeamStats& last_stats() const { return stats_; }

 private:
  GeometricSeamDetector(const GeometricSeamConfig& config, const hal::PinholeIntrinsics& K,
                        OrganizedCloud cloud, PlaneSegmenter planes, FilletFinder fillets);
  GeometricSeamConfig config_;
  hal::PinholeIntrinsics K_;
  OrganizedCloud cloud_;
  PlaneSegmenter planes_;
  FilletFinder fillets_;
  DetectionList candidates_;
  GeometricSeamStats stats_;
};

}  // namespace hwr::detect
