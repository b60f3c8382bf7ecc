#pragma once
// Summary statistics the benches print: the sample standard deviation (n - 1) of the paper's
// "mean ± sd" (hwr-bench frame, reloc).

#include <cmath>
#include <numeric>
#include <vector>

namespace hwr::bench {

// 0 for fewer than two values.
inline double sample_sd(const std::vector<double>& v) {
  if (v.size() < 2) return 0;
  const double m = std::accumulate(v.begin(), v.end(), 0.0) / static_cast<double>(v.size());
  double s = 0;
  for (const double x : v) s += (x - m) * (x - m);
  return std::sqrt(s / static_cast<double>(v.size() - 1));
}

}  // namespace hwr::bench
