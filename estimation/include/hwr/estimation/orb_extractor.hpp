#pragma once
// ORB features spread over the image (paper item 6; Rublee et al., ICCV 2011, with the cell-based
// distribution of ORB-SLAM, Mur-Artal et al., T-RO 2015 sec. III-A), each with the depth under it
// and its back-projected point (eq. 3).
//
// Per pyramid level: FAST-9 corners at the level's threshold (fast_threshold, raised on textured
// levels, see OrbConfig::corners_per_feature); a cell with none is searched again at
// min_fast_threshold (ORB-SLAM's retry of empty cells). The level's share of max_features is
// taken round-robin over the cells, best FAST response first, so every textured cell holds
// features before any cell holds two; a level that cannot fill its share passes the rest to the
// next. The orientation is the intensity centroid
// (ORB sec. 3.2); the descriptor is OpenCV's rBRIEF (learned 256-test pattern on the
// Gaussian-smoothed 31 x 31 patch, steered by the orientation), computed level by level on this
// extractor's pyramid.
//
// Memory: the pyramid, the candidate lists and the output are sized at construction. OpenCV's
// cv::FAST (one call per level plus one per empty cell searched again), cv::resize and ORB
// descriptor code (border copy, blur) allocate internally on every call: about 700 allocations
// per teddy frame and 950 per sim frame (tests/estimation/test_visual_odometry_tum.cpp and
// hwr-bench frame report them).
// State: the per-level thresholds carry from one frame to the next (a fresh extractor starts at
// fast_threshold), so the same image can give slightly different features on a later call.
// Time: hwr-bench micro --benchmark_filter=GridOrb (a teddy frame and a rendered sim lab frame).

#include <memory>
#include <vector>

#include <opencv2/core/mat.hpp>
#include <opencv2/core/types.hpp>
#include <opencv2/features2d.hpp>

#include "hwr/core/status.hpp"
#include "hwr/estimation/frame_features.hpp"
#include "hwr/hal/pinhole_camera.hpp"

namespace hwr::estimation {

struct OrbConfig {
  int max_features = 800;
  float scale_factor = 1.2f;
  int levels = 8;
  int fast_threshold = 20;
  int min_fast_threshold = 7;
  // Per-level FAST threshold control: on a textured level fast_threshold fires on so many pixels
  // that scoring them dominates the extraction, while the grid keeps only the strongest per cell.
  // A level whose last frame gave more than 2 x corners_per_feature corners per feature of its
  // budget raises its threshold (up to max_fast_threshold); one with fewer than half that lowers it
  // back towards fast_threshold. Cells left empty still get the min_fast_threshold retry, so dull
  // regions keep their features. 0 turns the control off.
  float corners_per_feature = 8.0f;
  int max_fast_threshold = 60;
  int grid_cell_px = 40;  // cell side in each level's own pixels
  float min_depth_m = 0.1f, max_depth_m = 10.0f;
  // Depth discontinuity: the keypoint's depth is rejected when its 3 x 3 neighbourhood has an
  // invalid pixel or spans more than this fraction of the centre depth.
  float max_depth_spread = 0.05f;
};

class GridOrbExtractor {
 public:
  GridOrbExtractor(const OrbConfig& config, int width, int height);
  ~GridOrbExtractor();
  GridOrbExtractor(const GridOrbExtractor&) = delete;
  GridOrbExtractor& operator=(const GridOrbExtractor&) = delete;

  // gray CV_8UC1 of the constructed size; depth_m CV_32FC1 of the same size (0 or non-finite =
  // invalid) or empty for no depth. out is cleared and refilled (level order), its grid rebuilt
  // and its scale_per_octave set. Errors: wrong image type/size, invalid intrinsics.
  core::Status extract(const cv::Mat& gray, const cv::Mat& depth_m, const hal::PinholeIntrinsics& K,
                       FrameFeatures* out);

  const OrbConfig& config() const { return config_; }
  // Features each level aims for (before carrying a shortfall to the next level).
  const std::vector<int>& level_budget() const { return level_budget_; }
  // The FAST threshold each level will use on the next frame (OrbConfig::corners_per_feature).
  const std::vector<int>& level_threshold() const { return level_threshold_; }

 private:
  struct Candidate {
    float x, y;  // level pixels
    float response;
    int cell;
  };
  void detect_level(int level);
  int select_level(int level, int budget);
  float ic_angle_deg(const cv::Mat& img, int x, int y) const;

  OrbConfig config_;
  int width_, height_;
  std::vector<float> scale_;
  std::vector<cv::Mat> pyramid_;
  std::vector<int> level_budget_;
  std::vector<int> level_threshold_;  // FAST threshold per level, adapted frame to frame
  std::vector<int> cell_cols_, cell_rows_;
  std::vector<int> umax_;  // half-width of the circular orientation patch per row

  // Scratch, reused every frame.
  std::vector<cv::KeyPoint> fast_kps_;
  std::vector<Candidate> candidates_;
  std::vector<int> cell_count_, cell_start_, order_, rank_pick_;
  std::vector<cv::KeyPoint> selected_;   // all levels in level order, level-0 coordinates, class_id = index
  std::vector<cv::KeyPoint> level_kps_;  // one level's keypoints in its own pixels
  cv::Mat descriptor_rows_;
  cv::Ptr<cv::ORB> orb_;
};

}  // namespace hwr::estimation
