#include "hwr/detect/seam_metrics.hpp"

#include <algorithm>
#include <cmath>

namespace hwr::detect {

double distance_to_line_m(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& u) {
  const Eigen::Vector3d off = p - a;
  return (off - off.dot(u) * u).norm();
}

SeamSegment seam_of(const Detection& d) {
  SeamSegment s;
  s.a = d.seam_world[0];
  s.b = d.seam_world[1];
  s.kind = d.kind;
  s.end_known = d.end_observed;
  return s;
}

SeamScore score_seams(const std::vector<SeamSegment>& detected, const std::vector<SeamSegment>& truth,
                      const SeamMatchConfig& config) {
  SeamScore score;
  score.detections = static_cast<int>(detected.size());
  score.truths = static_cast<int>(truth.size());
  struct Pair {
    double overlap_m;
    SeamMatch m;
  };
  std::vector<Pair> pairs;
  for (size_t i = 0; i < detected.size(); ++i) {
    const SeamSegment& d = detected[i];
    const double ld = (d.b - d.a).norm();
    if (ld < 1e-9) continue;
    for (size_t j = 0; j < truth.size(); ++j) {
      const SeamSegment& t = truth[j];
      const double lt = (t.b - t.a).norm();
      if (t.kind != d.kind || lt < 1e-9) continue;
      const Eigen::Vector3d ut = (t.b - t.a) / lt;
      const double cos_angle = std::fabs(ut.dot((d.b - d.a) / ld));
      if (std::acos(std::min(1.0, cos_angle)) > config.max_angle_rad) continue;
      SeamMatch m;
      m.detected = static_cast<int>(i);
      m.truth = static_cast<int>(j);
      m.lateral_m = std::max(distance_to_line_m(d.a, t.a, ut), distance_to_line_m(d.b, t.a, ut));
      if (m.lateral_m > config.max_lateral_m) continue;
      const double s0 = ut.dot(d.a - t.a), s1 = ut.dot(d.b - t.a);
      const double overlap = std::min(std::max(s0, s1), lt) - std::max(std::min(s0, s1), 0.0);
      if (overlap < config.min_overlap * std::min(ld, lt)) continue;
      // Ends paired by direction: the detected end nearer the true start is its start.
      const bool reversed = s1 < s0;
      for (int k = 0; k < 2; ++k) {
        const Eigen::Vector3d& de = k == 0 ? d.a : d.b;
        const int tk = reversed ? 1 - k : k;
        const Eigen::Vector3d& te = tk == 0 ? t.a : t.b;
        m.endpoint_m[k] = (de - te).norm();
        m.endpoint_valid[k] = d.end_known[k] && t.end_known[tk];
      }
      pairs.push_back({overlap, m});
    }
  }
  std::stable_sort(pairs.begin(), pairs.end(),
                   [](const Pair& x, const Pair& y) { return x.overlap_m > y.overlap_m; });
  std::vector<char> d_used(detected.size(), 0), t_used(truth.size(), 0);
  for (const Pair& p : pairs) {
    if (d_used[static_cast<size_t>(p.m.detected)] || t_used[static_cast<size_t>(p.m.truth)]) continue;
    d_used[static_cast<size_t>(p.m.detected)] = t_used[static_cast<size_t>(p.m.truth)] = 1;
    score.matches.push_back(p.m);
  }
  score.matched = static_cast<int>(score.matches.size());
  return score;
}

bool visible_seam_part(const SeamSegment& truth_world, const Eigen::Isometry3d& T_world_cam,
                       const hal::PinholeIntrinsics& K, const cv::Mat& depth_m, const DepthNoiseModel& noise,
                       double min_range_m, double max_range_m, double min_length_m, SeamSegment* out) {
  const Eigen::Vector3d camera_world = T_world_cam.translation();
  if (!truth_world.open_side.isZero() && (camera_world - truth_world.a).dot(truth_world.open_side) <= 0)
    return false;
  if (depth_m.empty() || depth_m.type() != CV_32FC1 || depth_m.cols != K.width || depth_m.rows != K.height)
    return false;
  const double length = (truth_world.b - truth_world.a).norm();
  const int n = std::max(2, static_cast<int>(std::ceil(length / 0.005)) + 1);
  const Eigen::Isometry3d T_cam_world = T_world_cam.inverse();
  constexpr double kMarginPx = 5.0;
  int first = -1, last = -1;
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector3d p_world =
        truth_world.a + (truth_world.b - truth_world.a) * (static_cast<double>(i) / (n - 1));
    const Eigen::Vector3d p = T_cam_world * p_world;
    if (p.z() < min_range_m || p.z() > max_range_m) continue;
    const double u = K.fx * p.x() / p.z() + K.cx, v = K.fy * p.y() / p.z() + K.cy;
    if (u < kMarginPx || v < kMarginPx || u > K.width - 1 - kMarginPx || v > K.height - 1 - kMarginPx)
      continue;
    const float z = depth_m.at<float>(static_cast<int>(std::lround(v)), static_cast<int>(std::lround(u)));
    if (!(std::isfinite(z) && z > 0)) continue;
    if (z < p.z() - (2.0 * noise.sigma_m(p.z()) + 0.003)) continue;  // something in front
    if (first < 0) first = i;
    last = i;
  }
  if (first < 0) return false;
  const Eigen::Vector3d d = truth_world.b - truth_world.a;
  *out = truth_world;
  out->a = truth_world.a + d * (static_cast<double>(first) / (n - 1));
  out->b = truth_world.a + d * (static_cast<double>(last) / (n - 1));
  out->end_known = {first == 0, last == n - 1};
  return (out->b - out->a).norm() >= min_length_m;
}

}  // namespace hwr::detect
