#pragma once
// Tracking by projection (ORB-SLAM's SearchByProjection, Mur-Artal et al., T-RO 2015 sec. V-B):
// map points are projected into the frame with a predicted pose and matched to the features near
// their projection by descriptor distance. Allocation-free after construction.

#include <cstdint>
#include <vector>

#include <Eigen/Geometry>

#include "hwr/estimation/frame_features.hpp"
#include "hwr/estimation/match_selection.hpp"
#include "hwr/hal/pinhole_camera.hpp"

namespace hwr::estimation {

struct MapPointRef {
  Eigen::Vector3d p_world;
  const uint8_t* descriptor;  // 32 bytes
  int octave_hint = -1;       // octave the point was seen at; -1: unknown (any octave, radius_px)
};

struct ProjectionMatchConfig {
  float radius_px = 12.f;  // search radius at octave 0, scaled by the octave's scale
  int max_distance = 64;   // Hamming
  float ratio = 0.9f;      // best < ratio * second best
  float min_depth_m = 0.05f;
  int octave_window = 2;  // candidate octaves: octave_hint +- window
};

class ProjectionMatcher {
 public:
  ProjectionMatcher(int max_points, int max_features);

  // Projects each map point with T_cam_world and K, searches the frame's grid in radius (scaled by
  // the point's octave scale), best Hamming distance with ratio test; a feature is matched at most
  // once (the better point keeps it). Writes at most max_out matches (ordered by frame feature),
  // returns the count. Points beyond max_points and features beyond max_features are ignored.
  int match(const MapPointRef* points, int n, const Eigen::Isometry3d& T_cam_world,
            const hal::PinholeIntrinsics& K, const FrameFeatures& frame, const ProjectionMatchConfig& cfg,
            FeatureMatch* out, int max_out);

 private:
  int max_points_;
  int max_features_;
  std::vector<int> candidates_;
  std::vector<int> distances_;  // the candidates' Hamming distances (hamming_kernel.hpp)
  TrainOwners owners_;          // per frame feature: the matched point and its distance
};

}  // namespace hwr::estimation
