#include "hwr/core/time_association.hpp"

#include <algorithm>
#include <tuple>

namespace hwr::core {

std::vector<IndexPair> associate_nearest(const std::vector<int64_t>& a, const std::vector<int64_t>& b,
                                         int64_t max_dt_ns, int64_t offset_ns) {
  struct Candidate {
    int64_t diff;
    size_t i, j;
  };
  std::vector<Candidate> candidates;
  size_t lo = 0;
  for (size_t i = 0; i < a.size(); ++i) {
    // Window of j with b[j] + offset in (a[i] - max_dt, a[i] + max_dt); lo only moves forward.
    while (lo < b.size() && b[lo] + offset_ns <= a[i] - max_dt_ns) ++lo;
    for (size_t j = lo; j < b.size() && b[j] + offset_ns < a[i] + max_dt_ns; ++j) {
      const int64_t d = a[i] - (b[j] + offset_ns);
      candidates.push_back({d < 0 ? -d : d, i, j});
    }
  }
  std::sort(candidates.begin(), candidates.end(), [](const Candidate& x, const Candidate& y) {
    return std::tie(x.diff, x.i, x.j) < std::tie(y.diff, y.i, y.j);
  });
  std::vector<bool> used_a(a.size(), false);
  std::vector<bool> used_b(b.size(), false);
  std::vector<IndexPair> out;
  for (const Candidate& c : candidates) {
    if (used_a[c.i] || used_b[c.j]) continue;
    used_a[c.i] = used_b[c.j] = true;
    out.push_back({c.i, c.j});
  }
  std::sort(out.begin(), out.end(), [](const IndexPair& x, const IndexPair& y) { return x.a < y.a; });
  return out;
}

}  // namespace hwr::core
