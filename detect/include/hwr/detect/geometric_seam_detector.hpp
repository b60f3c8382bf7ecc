#pragma once
// The geometric seam detector (issue #7 item 2): welding seams from the keyframe's depth and colour,
// no trained weights. The depth image is back-projected on a grid (organized_cloud.hpp), segmented into
// planes (plane_segmentation.hpp), and fillet joints are found among the planes (fillet_finder.hpp);
// plates lying raised on a horizontal support (raised_regions.hpp) are searched for a butt joint's gap
// line in the colour image and the depth (butt_finder.hpp; depth only without a colour image).
// Detections of one seam found twice (a plate split into two planes) are merged, the most confident
// max_detections kept, and each is placed in the world with the keyframe's pose. A butt line below the
// bar but above ButtConfig::support_z is a supporting detection (Detection::support_only): not a
// welding region, it goes to the fusion over keyframes only (seam_fusion.hpp). Sized at create();
// detect() allocates nothing.

#include <memory>

#include "hwr/detect/butt_finder.hpp"
#include "hwr/detect/detector.hpp"
#include "hwr/detect/fillet_finder.hpp"
#include "hwr/detect/organized_cloud.hpp"
#include "hwr/detect/plane_segmentation.hpp"
#include "hwr/detect/raised_regions.hpp"

namespace hwr::detect {

struct GeometricSeamConfig {
  DepthNoiseModel noise;
  OrganizedCloudConfig cloud;
  PlaneSegmentationConfig planes;
  FilletConfig fillet;
  RaisedRegionConfig raised;
  ButtConfig butt;
  int max_detections = 16;
  // Two detections are one seam when their lines are within these (the less confident is dropped).
  double duplicate_angle_rad = 0.175;
  double duplicate_distance_m = 0.03;
};

struct GeometricSeamStats {
  int valid_points = 0, planes = 0, raised_regions = 0, candidates = 0, duplicates = 0;
};

class GeometricSeamDetector final : public Detector {
 public:
  // Errors (kInvalidArgument): invalid K, a config value out of range (the parts' create()).
  static core::Expected<std::unique_ptr<GeometricSeamDetector>> create(const GeometricSeamConfig& config,
                                                                       const hal::PinholeIntrinsics& K);

  DetectionSource source() const override { return DetectionSource::kGeometry; }
  // Needs view.depth_m (CV_32FC1 of K's size); view.bgr (CV_8UC3 of K's size) when given: null or
  // empty is none (butt joints then from the depth alone), another type or size an error.
  core::Status detect(const KeyframeView& view, DetectionList* out) override;
  const GeometricSeamStats& last_stats() const { return stats_; }

 private:
  GeometricSeamDetector(const GeometricSeamConfig& config, const hal::PinholeIntrinsics& K,
                        OrganizedCloud cloud, PlaneSegmenter planes, FilletFinder fillets,
                        RaisedRegionFinder raised, ButtFinder butts);
  GeometricSeamConfig config_;
  hal::PinholeIntrinsics K_;
  OrganizedCloud cloud_;
  PlaneSegmenter planes_;
  FilletFinder fillets_;
  RaisedRegionFinder raised_;
  ButtFinder butts_;
  DetectionList candidates_;
  GeometricSeamStats stats_;
};

}  // namespace hwr::detect
