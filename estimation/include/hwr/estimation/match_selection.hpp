#pragma once
// The selection rules the descriptor matchers share (projection_matcher, lsh_matcher,
// exact_matcher): the two nearest candidates of a query for Lowe's ratio test, and one match per
// train feature, the closer query keeping it, written out in train order. Header-only, no
// allocation after construction: the projection matcher runs on the per-frame path.

#include <algorithm>
#include <vector>

namespace hwr::estimation {

// query: map point / feature of A; train: feature index in the frame / B.
struct FeatureMatch {
  int query = -1;
  int train = -1;
  int distance = 256;
};

// The nearest and second-nearest distances seen, and the nearest's index (-1: none yet).
struct TwoNearest {
  int best = 257, second = 257, index = -1;
  void add(int distance, int j) {
    if (distance < best) {
      second = best;
      best = distance;
      index = j;
    } else if (distance < second) {
      second = distance;
    }
  }
};

// One match per train feature: offer() keeps the closest query of each (a distance of 256, every bit
// differing, never owns one), write() emits them ordered by train index.
class TrainOwners {
 public:
  explicit TrainOwners(int capacity)
      : owner_(static_cast<size_t>(std::max(capacity, 1)), -1),
        distance_(static_cast<size_t>(std::max(capacity, 1)), kNone) {}
  // Clears the first n_train entries (n_train <= capacity).
  void reset(int n_train) {
    n_ = n_train;
    std::fill(owner_.begin(), owner_.begin() + n_, -1);
    std::fill(distance_.begin(), distance_.begin() + n_, kNone);
  }
  void offer(int train, int query, int distance) {
    const size_t j = static_cast<size_t>(train);
    if (distance < distance_[j]) {
      owner_[j] = query;
      distance_[j] = distance;
    }
  }
  // At most max_out matches, ordered by train index; returns the count.
  int write(FeatureMatch* out, int max_out) const {
    int count = 0;
    for (int j = 0; j < n_ && count < max_out; ++j) {
      if (owner_[static_cast<size_t>(j)] < 0) continue;
      out[count++] = {owner_[static_cast<size_t>(j)], j, distance_[static_cast<size_t>(j)]};
    }
    return count;
  }

 private:
  static constexpr int kNone = 256;
  int n_ = 0;
  std::vector<int> owner_, distance_;
};

}  // namespace hwr::estimation
