#include "hwr/estimation/exact_matcher.hpp"

#include <algorithm>
#include <cstring>

#include "hwr/estimation/descriptor.hpp"

namespace hwr::estimation {

ExactMatcher::ExactMatcher(int max_descriptors, const ExactMatchConfig& cfg)
    : max_descriptors_(std::max(max_descriptors, 1)),
      cfg_(cfg),
      train_(max_descriptors_, kOrbDescriptorBytes, CV_8U, cv::Scalar(0)),
      owner_(static_cast<size_t>(max_descriptors_), -1),
      owner_d_(static_cast<size_t>(max_descriptors_), kOrbDescriptorBits) {}

void ExactMatcher::build(const FrameFeatures& train) {
  n_train_ = std::min(train.size(), max_descriptors_);
  if (n_train_ > 0) {
    std::memcpy(train_.data, train.descriptor(0), static_cast<size_t>(n_train_) * kOrbDescriptorBytes);
  }
}

int ExactMatcher::match(const FrameFeatures& query, FeatureMatch* out, int max_out) {
  const int nq = std::min(query.size(), max_descriptors_);
  if (n_train_ == 0 || nq == 0) return 0;
  // A header over the query's storage (rows are contiguous 32-byte descriptors).
  const cv::Mat q(nq, kOrbDescriptorBytes, CV_8U, const_cast<uint8_t*>(query.descriptor(0)));
  const int k = std::min(2, n_train_);
  cv::batchDistance(q, train_.rowRange(0, n_train_), dist_, CV_32S, nidx_, cv::NORM_HAMMING, k);
  std::fill(owner_.begin(), owner_.begin() + n_train_, -1);
  std::fill(owner_d_.begin(), owner_d_.begin() + n_train_, kOrbDescriptorBits);
  for (int i = 0; i < nq; ++i) {
    const int* d = dist_.ptr<int>(i);
    const int* j = nidx_.ptr<int>(i);
    if (j[0] < 0 || j[0] >= n_train_) continue;
    const int best = d[0];
    if (best > cfg_.max_distance) continue;
    if (k == 2 && j[1] >= 0 && static_cast<float>(best) >= cfg_.ratio * static_cast<float>(d[1])) continue;
    if (best < owner_d_[static_cast<size_t>(j[0])]) {
      owner_[static_cast<size_t>(j[0])] = i;
      owner_d_[static_cast<size_t>(j[0])] = best;
    }
  }
  int count = 0;
  for (int t = 0; t < n_train_ && count < max_out; ++t) {
    if (owner_[static_cast<size_t>(t)] < 0) continue;
    out[count++] = {owner_[static_cast<size_t>(t)], t, owner_d_[static_cast<size_t>(t)]};
  }
  return count;
}

}  // namespace hwr::estimation
