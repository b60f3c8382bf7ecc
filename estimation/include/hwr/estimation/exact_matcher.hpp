#pragma once
// Exhaustive descriptor matching between two keyframes (relocalization: the current keyframe
// against one prior keyframe at a time, ~800 x 800): the exact 2 nearest neighbours by Hamming
// distance (OpenCV's cv::batchDistance, NORM_HAMMING, K = 2: its vectorised popcount), Lowe's ratio
// test and max_distance, one match per train feature (the closer query keeps it). The same contract
// as LshMatcher (lsh_matcher.hpp) without its misses: LSH finds the nearest neighbour only when a
// probed bucket holds it, and the second rarely, so its ratio test is weaker. At these sizes it is
// also faster than probing FLANN's 12 tables (hwr-bench micro --benchmark_filter='Lsh|Exact', teddy
// frames: 2.9 ms per match against LSH's 6.0 ms, 146 against 155 matches).
//
// Off the per-frame path (the relocalization worker's thread): build() copies the train descriptors
// into a buffer sized at construction; match() keeps its output matrices, but cv::batchDistance
// allocates working memory on every call (64 allocations for 500 x 500).

#include <vector>

#include <opencv2/core.hpp>

#include "hwr/estimation/frame_features.hpp"
#include "hwr/estimation/projection_matcher.hpp"

namespace hwr::estimation {

struct ExactMatchConfig {
  int max_distance = 64;  // Hamming bits
  float ratio = 0.8f;     // best < ratio x second best
};

class ExactMatcher {
 public:
  ExactMatcher(int max_descriptors, const ExactMatchConfig& cfg);

  // Keeps a copy of train's descriptors (at most max_descriptors).
  void build(const FrameFeatures& train);
  int indexed() const { return n_train_; }
  // Each query descriptor's 2 nearest train descriptors, ratio test + max_distance, one match per
  // train feature. Writes at most max_out (ordered by train index), returns the count; 0 before build().
  int match(const FrameFeatures& query, FeatureMatch* out, int max_out);

 private:
  int max_descriptors_;
  ExactMatchConfig cfg_;
  int n_train_ = 0;
  cv::Mat train_;        // max_descriptors x 32 CV_8U
  cv::Mat dist_, nidx_;  // batchDistance's output: query x 2 (CV_32S)
  std::vector<int> owner_, owner_d_;
};

}  // namespace hwr::estimation
