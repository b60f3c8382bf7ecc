#include "hwr/estimation/lsh_matcher.hpp"

#include <algorithm>
#include <cstring>
#include <limits>

#include <flann/flann.hpp>

#include "hwr/estimation/descriptor.hpp"

namespace hwr::estimation {

namespace {

using HammingDistance = flann::Hamming<unsigned char>;
using DistanceType = HammingDistance::ResultType;

// The two nearest distinct neighbours seen so far. FLANN's LSH visits a point once per table and
// probe that holds it, so repeated indices are ignored. Fixed size: querying allocates nothing
// (FLANN's own KNN result sets allocate per knnSearch call).
class FlannTwoNearest : public flann::ResultSet<DistanceType> {
 public:
  void reset() {
    d_[0] = d_[1] = std::numeric_limits<DistanceType>::max();
    i_[0] = i_[1] = kNone;
  }
  bool full() const override { return i_[1] != kNone; }
  DistanceType worstDist() const override { return d_[1]; }
  void addPoint(DistanceType dist, size_t index) override {
    if (index == i_[0] || index == i_[1]) return;
    if (dist < d_[0]) {
      d_[1] = d_[0];
      i_[1] = i_[0];
      d_[0] = dist;
      i_[0] = index;
    } else if (dist < d_[1]) {
      d_[1] = dist;
      i_[1] = index;
    }
  }
  static constexpr size_t kNone = static_cast<size_t>(-1);
  size_t index(int k) const { return i_[k]; }
  DistanceType distance(int k) const { return d_[k]; }

 private:
  DistanceType d_[2];
  size_t i_[2];
};

}  // namespace

struct LshMatcher::Index {
  Index(const flann::Matrix<unsigned char>& data, const LshConfig& cfg)
      : lsh(data,
            flann::LshIndexParams(static_cast<unsigned>(cfg.tables), static_cast<unsigned>(cfg.key_bits),
                                  static_cast<unsigned>(cfg.multi_probe))) {
    lsh.buildIndex();
  }
  flann::LshIndex<HammingDistance> lsh;
};

LshMatcher::LshMatcher(int max_descriptors, const LshConfig& cfg)
    : max_descriptors_(std::max(max_descriptors, 1)),
      cfg_(cfg),
      train_(static_cast<size_t>(max_descriptors_) * kOrbDescriptorBytes, 0),
      owners_(max_descriptors_) {
  // FLANN's LSH keys are at most 32 bits; keep the configuration inside what it accepts.
  cfg_.tables = std::max(1, cfg_.tables);
  cfg_.key_bits = std::clamp(cfg_.key_bits, 1, 31);
  cfg_.multi_probe = std::max(0, cfg_.multi_probe);
}

LshMatcher::~LshMatcher() = default;

void LshMatcher::build(const FrameFeatures& train) {
  n_train_ = std::min(train.size(), max_descriptors_);
  index_.reset();
  if (n_train_ == 0) return;
  for (int i = 0; i < n_train_; ++i) {
    std::memcpy(&train_[static_cast<size_t>(i) * kOrbDescriptorBytes], train.descriptor(i),
                kOrbDescriptorBytes);
  }
  const flann::Matrix<unsigned char> data(train_.data(), static_cast<size_t>(n_train_), kOrbDescriptorBytes);
  index_ = std::make_unique<Index>(data, cfg_);
}

int LshMatcher::match(const FrameFeatures& query, FeatureMatch* out, int max_out) {
  if (!index_ || n_train_ == 0) return 0;
  const int nq = std::min(query.size(), max_descriptors_);
  if (nq == 0) return 0;
  owners_.reset(n_train_);
  const flann::SearchParams params;
  FlannTwoNearest nn;
  for (int q = 0; q < nq; ++q) {
    nn.reset();
    index_->lsh.findNeighbors(nn, query.descriptor(q), params);
    const size_t j = nn.index(0);
    if (j >= static_cast<size_t>(n_train_)) continue;
    const int best = static_cast<int>(nn.distance(0));
    if (best > cfg_.max_distance) continue;
    // Lowe's ratio test against the second neighbour LSH found (none found: no ambiguity seen).
    if (nn.index(1) < static_cast<size_t>(n_train_) &&
        static_cast<float>(best) >= cfg_.ratio * static_cast<float>(nn.distance(1))) {
      continue;
    }
    owners_.offer(static_cast<int>(j), q, best);
  }
  return owners_.write(out, max_out);
}

}  // namespace hwr::estimation
