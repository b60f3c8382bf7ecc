#pragma once
// Wide descriptor search without a pose (tracking lost, keyframe-to-keyframe matching for
// triangulation, paper item 6): multi-probe LSH over binary descriptors (Lv et al., VLDB 2007;
// FLANN's LshIndex, Muja & Lowe 2014), 2 nearest neighbours and Lowe's ratio test.
//
// Not on the per-frame path: FLANN allocates its hash tables on every build() (about 23 000
// allocations for 1000 descriptors with the default 12 tables); match() allocates nothing
// (a fixed 2-NN result set instead of FLANN's knnSearch). tests/estimation/test_matchers.cpp
// counts both. FLANN picks each table's key bits with
// std::random_device, so matches vary slightly between runs.

#include <cstdint>
#include <memory>
#include <vector>

#include "hwr/estimation/frame_features.hpp"
#include "hwr/estimation/projection_matcher.hpp"

namespace hwr::estimation {

struct LshConfig {
  int tables = 12;
  int key_bits = 20;
  int multi_probe = 2;
  int max_distance = 64;
  float ratio = 0.8f;
};

class LshMatcher {
 public:
  LshMatcher(int max_descriptors, const LshConfig& cfg);
  ~LshMatcher();
  LshMatcher(const LshMatcher&) = delete;
  LshMatcher& operator=(const LshMatcher&) = delete;

  // Indexes train's descriptors (copied; train may change afterwards). At most max_descriptors.
  void build(const FrameFeatures& train);
  int indexed() const { return n_train_; }
  // 2-NN of each query descriptor in the index, ratio test + max_distance, one match per train
  // feature (the closer query keeps it). Writes at most max_out (ordered by train index), returns
  // the count; 0 before build().
  int match(const FrameFeatures& query, FeatureMatch* out, int max_out);

 private:
  struct Index;
  int max_descriptors_;
  LshConfig cfg_;
  int n_train_ = 0;
  std::vector<uint8_t> train_;  // max_descriptors x 32
  TrainOwners owners_;
  std::vector<size_t> knn_indices_;      // max_descriptors x 2
  std::vector<unsigned int> knn_dists_;  // max_descriptors x 2
  std::unique_ptr<Index> index_;
};

}  // namespace hwr::estimation
