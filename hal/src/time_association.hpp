#pragma once
// Private to hal: association of two timestamp lists as TUM's associate.py does it. (The same
// rule lives in estimation's trajectory_metrics for trajectories; it belongs in core once core
// has a home for it.)

#include <cstddef>
#include <cstdint>
#include <vector>

namespace hwr::hal {

struct IndexPair {
  size_t a = 0;
  size_t b = 0;
};

// Both lists strictly increasing. Candidates are all (i, j) with |a[i] - (b[j] + offset_ns)| <
// max_dt_ns; they are taken greedily by increasing difference (ties: lower i, then lower j), each
// index at most once. The result is sorted by a.
std::vector<IndexPair> associate_nearest(const std::vector<int64_t>& a, const std::vector<int64_t>& b,
                                         int64_t max_dt_ns, int64_t offset_ns = 0);

}  // namespace hwr::hal
