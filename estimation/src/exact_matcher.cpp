#include "hwr/estimation/exact_matcher.hpp"

#include <algorithm>
#include <cstring>

#include "hwr/estimation/descriptor.hpp"

namespace hwr::estimation {

ExactMatcher::ExactMatcher(int max_descriptors, const ExactMatchConfig& cfg)
    : max_descriptors_(std::max(max_descriptors, 1)),
      cfg_(cfg),
      train_(static_cast<size_t>(max_descriptors_) * kOrbDescriptorBytes, 0),
      owner_(static_cast<size_t>(max_descriptors_), -1),
      owner_d_(static_cast<size_t>(max_descriptors_), kOrbDescriptorBits + 1) {}

void ExactMatcher::build(const FrameFeatures& train) {
  n_train_ = std::min(train.size(), max_descriptors_);
  if (n_train_ > 0) {
    std::memcpy(train_.data(), train.descriptor(0), static_cast<size_t>(n_train_) * kOrbDescriptorBytes);
  }
}

int ExactMatcher::match(const FrameFeatures& query, FeatureMatch* out, int max_out) {
  const int nq = std::min(query.size(), max_descriptors_);
  if (n_train_ == 0 || nq == 0) return 0;
  std::fill(owner_.begin(), owner_.begin() + n_train_, -1);
  std::fill(owner_d_.begin(), owner_d_.begin() + n_train_, kOrbDescriptorBits + 1);
  for (int i = 0; i < nq; ++i) {
    const uint8_t* qd = query.descriptor(i);
    int best = kOrbDescriptorBits + 1, second = kOrbDescriptorBits + 1, j = -1;
    for (int t = 0; t < n_train_; ++t) {
      const int d = hamming_distance(qd, &train_[static_cast<size_t>(t) * kOrbDescriptorBytes]);
      if (d < best) {
        second = best;
        best = d;
        j = t;
      } else if (d < second) {
        second = d;
      }
    }
    if (j < 0 || best > cfg_.max_distance) continue;
    // Lowe's ratio test against the true second neighbour (none with a single train descriptor).
    if (n_train_ > 1 && static_cast<float>(best) >= cfg_.ratio * static_cast<float>(second)) continue;
    if (best < owner_d_[static_cast<size_t>(j)]) {
      owner_[static_cast<size_t>(j)] = i;
      owner_d_[static_cast<size_t>(j)] = best;
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
