#pragma once
// Exhaustive descriptor matching between two keyframes (relocalization: the current keyframe
// against one prior keyframe at a time, ~800 x 800): the exact 2 nearest neighbours by Hamming
// distance (descriptor.hpp), Lowe's ratio test and max_distance, one match per train feature (the
// closer query keeps it). The same contract as LshMatcher (lsh_matcher.hpp) without its misses: LSH
// finds the nearest neighbour only when a probed bucket holds it, and the second rarely, so its ratio
// test is weaker. At these sizes it is also faster than probing FLANN's 12 tables (hwr-bench micro
// --benchmark_filter='Lsh|Exact', teddy frames, one thread: see docs/estimation.md).
//
// A plain loop on the caller's thread (one query row at a time through hamming_kernel.hpp, which
// uses the CPU's population count instruction where it has one), not cv::batchDistance: that one runs on
// OpenCV's thread pool (every core, beside the control loop) and allocates on every call. build() copies the
// train descriptors into a buffer sized at construction; match() allocates nothing.

#include <cstdint>
#include <vector>

#include "hwr/estimation/frame_features.hpp"
#include "hwr/estimation/match_selection.hpp"

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
  std::vector<uint8_t> train_;  // max_descriptors x 32
  TrainOwners owners_;
  std::vector<int> distances_;  // one query row's distances to every train descriptor
};

}  // namespace hwr::estimation
