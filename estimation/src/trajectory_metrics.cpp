#include "hwr/estimation/trajectory_metrics.hpp"

#include "hwr/core/time_association.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <string>
#include <tuple>

#include <Eigen/Geometry>

#include "hwr/core/time.hpp"

namespace hwr::estimation {
namespace {

using core::StampedPose;

// Indices of poses sorted by time (stable for equal stamps).
std::vector<size_t> time_order(const std::vector<StampedPose>& poses) {
  std::vector<size_t> idx(poses.size());
  std::iota(idx.begin(), idx.end(), size_t{0});
  std::stable_sort(idx.begin(), idx.end(), [&](size_t a, size_t b) { return poses[a].t_ns < poses[b].t_ns; });
  return idx;
}

// Index of the element of sorted `v` closest to `x`; ties go to the lower index.
template <class T>
size_t closest_index(const std::vector<T>& v, T x) {
  const auto it = std::lower_bound(v.begin(), v.end(), x);
  if (it == v.begin()) return 0;
  if (it == v.end()) return v.size() - 1;
  const size_t hi = static_cast<size_t>(it - v.begin());
  return (x - v[hi - 1] <= *it - x) ? hi - 1 : hi;
}

double median_of(std::vector<double> v) {
  if (v.empty()) return 0;
  const size_t n = v.size();
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(n / 2), v.end());
  const double upper = v[n / 2];
  if (n % 2 == 1) return upper;
  const double lower = *std::max_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(n / 2));
  return 0.5 * (lower + upper);
}

}  // namespace

ErrorStats compute_error_stats(const std::vector<double>& errors) {
  ErrorStats s;
  s.count = errors.size();
  if (errors.empty()) return s;
  double sum = 0;
  double sum_sq = 0;
  s.min = errors.front();
  s.max = errors.front();
  for (double e : errors) {
    sum += e;
    sum_sq += e * e;
    s.min = std::min(s.min, e);
    s.max = std::max(s.max, e);
  }
  const double n = static_cast<double>(errors.size());
  s.mean = sum / n;
  s.rmse = std::sqrt(sum_sq / n);
  double var = 0;
  for (double e : errors) var += (e - s.mean) * (e - s.mean);
  s.std = std::sqrt(var / n);
  s.median = median_of(errors);
  return s;
}

std::vector<PoseMatch> associate_by_time(const std::vector<StampedPose>& gt,
                                         const std::vector<StampedPose>& est, double max_dt_s,
                                         double offset_s) {
  // core::associate_nearest wants each list in time order; map its indices back afterwards.
  const std::vector<size_t> og = time_order(gt);
  const std::vector<size_t> oe = time_order(est);
  std::vector<int64_t> t_gt(og.size()), t_est(oe.size());
  for (size_t k = 0; k < og.size(); ++k) t_gt[k] = gt[og[k]].t_ns;
  for (size_t k = 0; k < oe.size(); ++k) t_est[k] = est[oe[k]].t_ns;
  std::vector<PoseMatch> out;
  for (const core::IndexPair& p :
       core::associate_nearest(t_gt, t_est, core::s_to_ns(max_dt_s), core::s_to_ns(offset_s))) {
    out.push_back({og[p.a], oe[p.b]});
  }
  std::sort(out.begin(), out.end(), [](const PoseMatch& x, const PoseMatch& y) { return x.gt < y.gt; });
  return out;
}

core::Expected<AteResult> compute_ate(const std::vector<StampedPose>& gt, const std::vector<StampedPose>& est,
                                      const AteOptions& options) {
  AteResult r;
  r.matches = associate_by_time(gt, est, options.max_dt_s, options.offset_s);
  r.pairs = r.matches.size();
  if (r.pairs < 3) {
    return core::InvalidArgument("ATE needs at least 3 associated poses, found " + std::to_string(r.pairs) +
                                 " (" + std::to_string(gt.size()) + " ground-truth, " +
                                 std::to_string(est.size()) + " estimated poses, max_dt " +
                                 std::to_string(options.max_dt_s) + " s, offset " +
                                 std::to_string(options.offset_s) + " s)");
  }
  Eigen::Matrix3Xd p_gt(3, static_cast<Eigen::Index>(r.pairs));
  Eigen::Matrix3Xd p_est(3, static_cast<Eigen::Index>(r.pairs));
  for (size_t k = 0; k < r.pairs; ++k) {
    p_gt.col(static_cast<Eigen::Index>(k)) = gt[r.matches[k].gt].T_world_body.translation();
    p_est.col(static_cast<Eigen::Index>(k)) = est[r.matches[k].est].T_world_body.translation();
  }
  // Umeyama (1991), Eqs. (40)-(42): p_gt ≈ c·R·p_est + t in the least-squares sense.
  const Eigen::Matrix4d S = Eigen::umeyama(p_est, p_gt, options.sim3);
  if (!S.allFinite()) return core::Internal("ATE: alignment is not finite (degenerate trajectory?)");
  const Eigen::Matrix3d cR = S.topLeftCorner<3, 3>();
  r.scale = options.sim3 ? std::cbrt(cR.determinant()) : 1.0;
  r.T_gt_est.setIdentity();
  r.T_gt_est.linear() = cR / r.scale;
  r.T_gt_est.translation() = S.topRightCorner<3, 1>();

  r.errors_m.resize(r.pairs);
  for (size_t k = 0; k < r.pairs; ++k) {
    const Eigen::Index c = static_cast<Eigen::Index>(k);
    r.errors_m[k] = (p_gt.col(c) - (cR * p_est.col(c) + r.T_gt_est.translation())).norm();
  }
  r.translation_m = compute_error_stats(r.errors_m);
  return r;
}

core::Expected<RpeResult> compute_rpe(const std::vector<StampedPose>& gt, const std::vector<StampedPose>& est,
                                      const RpeOptions& options) {
  if (gt.size() < 2 || est.size() < 2) {
    return core::InvalidArgument("RPE needs at least 2 ground-truth and 2 estimated poses, got " +
                                 std::to_string(gt.size()) + " and " + std::to_string(est.size()));
  }
  if (!(options.delta > 0)) return core::InvalidArgument("RPE: delta must be > 0");
  const std::vector<size_t> og = time_order(gt);
  const std::vector<size_t> oe = time_order(est);
  std::vector<int64_t> t_gt(og.size());
  std::vector<int64_t> t_est(oe.size());
  for (size_t k = 0; k < og.size(); ++k) t_gt[k] = gt[og[k]].t_ns;
  for (size_t k = 0; k < oe.size(); ++k) t_est[k] = est[oe[k]].t_ns;
  const int64_t offset_ns = core::s_to_ns(options.offset_s);

  std::vector<double> gt_dt(t_gt.size() - 1);
  for (size_t k = 1; k < t_gt.size(); ++k) gt_dt[k - 1] = static_cast<double>(t_gt[k] - t_gt[k - 1]);
  const double gt_max_diff_ns = 2.0 * median_of(gt_dt);

  RpeResult r;
  const size_t n = oe.size();
  const int64_t delta_ns = core::s_to_ns(options.delta);
  for (size_t i = 0; i < n; ++i) {
    size_t j = 0;
    if (options.delta_unit == DeltaUnit::kSeconds) {
      j = closest_index(t_est, t_est[i] + delta_ns);
    } else {
      // Closest frame number, ties to the lower one.
      const double target = static_cast<double>(i) + options.delta;
      j = target >= static_cast<double>(n - 1) ? n - 1 : static_cast<size_t>(std::ceil(target - 0.5));
    }
    if (j == n - 1) continue;  // evaluate_rpe.py drops pairs ending on the last pose
    const size_t g0 = closest_index(t_gt, t_est[i] + offset_ns);
    const size_t g1 = closest_index(t_gt, t_est[j] + offset_ns);
    if (std::fabs(static_cast<double>(t_gt[g0] - (t_est[i] + offset_ns))) > gt_max_diff_ns ||
        std::fabs(static_cast<double>(t_gt[g1] - (t_est[j] + offset_ns))) > gt_max_diff_ns) {
      ++r.skipped_no_gt;
      continue;
    }
    const Eigen::Isometry3d& P_i = est[oe[i]].T_world_body;
    const Eigen::Isometry3d& P_j = est[oe[j]].T_world_body;
    const Eigen::Isometry3d& Q_i = gt[og[g0]].T_world_body;
    const Eigen::Isometry3d& Q_j = gt[og[g1]].T_world_body;
    const Eigen::Isometry3d E = (P_i.inverse() * P_j) * (Q_i.inverse() * Q_j).inverse();
    r.est_pairs.emplace_back(oe[i], oe[j]);
    r.translation_errors_m.push_back(E.translation().norm());
    r.rotation_errors_rad.push_back(Eigen::AngleAxisd(Eigen::Quaterniond(E.linear()).normalized()).angle());
  }
  r.pairs = r.est_pairs.size();
  if (r.pairs < 3) {
    return core::InvalidArgument("RPE needs at least 3 pose pairs " + std::to_string(options.delta) +
                                 (options.delta_unit == DeltaUnit::kSeconds ? " s" : " frames") +
                                 " apart, found " + std::to_string(r.pairs) + " (" +
                                 std::to_string(r.skipped_no_gt) +
                                 " without ground truth within 2 median intervals)");
  }
  r.translation_m = compute_error_stats(r.translation_errors_m);
  r.rotation_rad = compute_error_stats(r.rotation_errors_rad);
  return r;
}

}  // namespace hwr::estimation
