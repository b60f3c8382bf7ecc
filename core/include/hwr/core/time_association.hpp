#pragma once
// Association of two timestamp lists as TUM's associate.py does it: used to pair colour and depth
// images, stereo frames, and estimated with ground-truth poses.

#include <cstddef>
#include <cstdint>
#include <vector>

namespace hwr::core {

struct IndexPair {
  size_t a = 0;
  size_t b = 0;
};

// Both lists strictly increasing. Candidates are all (i, j) with |a[i] - (b[j] + offset_ns)| <
// max_dt_ns; they are taken greedily by increasing difference (ties: lower i, then lower j), each
// index at most once. The result is sorted by a.
std::vector<IndexPair> associate_nearest(const std::vector<int64_t>& a, const std::vector<int64_t>& b,
                                         int64_t max_dt_ns, int64_t offset_ns = 0);

}  // namespace hwr::core
