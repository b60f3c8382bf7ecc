#include "hwr/estimation/exact_matcher.hpp"

#include <algorithm>
#include <cstring>

#include "hwr/estimation/descriptor.hpp"
#include "hwr/estimation/hamming_kernel.hpp"

namespace hwr::estimation {

ExactMatcher::ExactMatcher(int max_descriptors, const ExactMatchConfig& cfg)
    : max_descriptors_(std::max(max_descriptors, 1)),
      cfg_(cfg),
      train_(static_cast<size_t>(max_descriptors_) * kOrbDescriptorBytes, 0),
      owners_(max_descriptors_),
      distances_(static_cast<size_t>(max_descriptors_)) {}

void ExactMatcher::build(const FrameFeatures& train) {
  n_train_ = std::min(train.size(), max_descriptors_);
  if (n_train_ > 0) {
    std::memcpy(train_.data(), train.descriptor(0), static_cast<size_t>(n_train_) * kOrbDescriptorBytes);
  }
}

int ExactMatcher::match(const FrameFeatures& query, FeatureMatch* out, int max_out) {
  const int nq = std::min(query.size(), max_descriptors_);
  if (n_train_ == 0 || nq == 0) return 0;
  owners_.reset(n_train_);
  for (int i = 0; i < nq; ++i) {
    const uint8_t* qd = query.descriptor(i);
    hamming_distances(qd, train_.data(), n_train_, distances_.data());
    TwoNearest nn;
    for (int t = 0; t < n_train_; ++t) nn.add(distances_[static_cast<size_t>(t)], t);
    if (nn.index < 0 || nn.best > cfg_.max_distance) continue;
    // Lowe's ratio test against the true second neighbour (none with a single train descriptor).
    if (n_train_ > 1 && static_cast<float>(nn.best) >= cfg_.ratio * static_cast<float>(nn.second)) continue;
    owners_.offer(nn.index, i, nn.best);
  }
  return owners_.write(out, max_out);
}

}  // namespace hwr::estimation
