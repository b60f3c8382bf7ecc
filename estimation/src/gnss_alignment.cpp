#include "hwr/estimation/gnss_alignment.hpp"

#include <cmath>

namespace hwr::estimation {

namespace {

struct Fit {
  double yaw = 0;
  Eigen::Vector3d t = Eigen::Vector3d::Zero();
  double spread2 = 0;  // sum |p_world,xy - centroid|^2 of the pairs used
};

// One weighted fit over the pairs with use[k] set (equal horizontal weights: one sigma_h for all).
Fit fit_once(const std::vector<Eigen::Vector3d>& w, const std::vector<Eigen::Vector3d>& e,
             const std::vector<bool>& use, double fixed_yaw) {
  Eigen::Vector3d cw = Eigen::Vector3d::Zero(), ce = Eigen::Vector3d::Zero();
  int n = 0;
  for (size_t k = 0; k < w.size(); ++k) {
    if (!use[k]) continue;
    cw += w[k];
    ce += e[k];
    ++n;
  }
  cw /= n;
  ce /= n;
  Fit f;
  double s_cos = 0, s_sin = 0;
  for (size_t k = 0; k < w.size(); ++k) {
    if (!use[k]) continue;
    const Eigen::Vector2d a = (w[k] - cw).head<2>(), b = (e[k] - ce).head<2>();
    s_cos += a.dot(b);
    s_sin += a.x() * b.y() - a.y() * b.x();
    f.spread2 += a.squaredNorm();
  }
  f.yaw = std::isfinite(fixed_yaw) ? fixed_yaw : std::atan2(s_sin, s_cos);
  const Eigen::Matrix3d R = Eigen::AngleAxisd(f.yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  f.t = ce - R * cw;  // horizontal: centroids; vertical: mean of z_e - z_w (R keeps z)
  return f;
}

}  // namespace

GnssAlignment fit_T_enu_world(const std::vector<Eigen::Vector3d>& p_world,
                              const std::vector<Eigen::Vector3d>& p_enu, double sigma_h_m, double sigma_v_m,
                              double fixed_yaw_rad, const GnssAlignmentConfig& config) {
  GnssAlignment out;
  if (p_world.size() != p_enu.size()) {
    out.reason = "gnss alignment: " + std::to_string(p_world.size()) + " world positions but " +
                 std::to_string(p_enu.size()) + " ENU positions";
    return out;
  }
  if (!(sigma_h_m > 0) || !(sigma_v_m > 0) || !std::isfinite(sigma_h_m) || !std::isfinite(sigma_v_m)) {
    out.reason = "gnss alignment: the fixes' sigmas must be positive and finite";
    return out;
  }
  std::vector<bool> use(p_world.size());
  int n = 0;
  for (size_t k = 0; k < use.size(); ++k) {
    use[k] = p_world[k].allFinite() && p_enu[k].allFinite();
    n += use[k] ? 1 : 0;
  }
  const int finite_pairs = n;
  Fit f;
  for (int round = 0;; ++round) {
    if (n < std::max(config.min_pairs, 1)) {
      out.reason = "gnss alignment: " + std::to_string(n) + " usable pairs, need " +
                   std::to_string(std::max(config.min_pairs, 1));
      return out;
    }
    f = fit_once(p_world, p_enu, use, fixed_yaw_rad);
    const Eigen::Matrix3d R = Eigen::AngleAxisd(f.yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    // Drop the worst pair beyond the gate, one per round: a gross outlier distorts the fit, and
    // with it the residuals of good pairs, until it is gone.
    double worst = config.outlier_sigmas * sigma_h_m;
    size_t worst_k = use.size();
    for (size_t k = 0; k < use.size(); ++k) {
      if (!use[k]) continue;
      const double r = (R * p_world[k] + f.t - p_enu[k]).head<2>().norm();
      if (r > worst) {
        worst = r;
        worst_k = k;
      }
    }
    if (worst_k == use.size() || round >= static_cast<int>(use.size())) break;
    use[worst_k] = false;
    --n;
  }
  const Eigen::Matrix3d R = Eigen::AngleAxisd(f.yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  double ss = 0;
  for (size_t k = 0; k < use.size(); ++k)
    if (use[k]) ss += (R * p_world[k] + f.t - p_enu[k]).head<2>().squaredNorm();
  out.pairs_used = n;
  out.pairs_dropped = finite_pairs - n;
  out.rms_horizontal_m = std::sqrt(ss / n);
  out.yaw_rad = std::remainder(f.yaw, 2.0 * M_PI);
  out.T_enu_world.linear() = R;
  out.T_enu_world.translation() = f.t;
  out.horizontal_sigma_m = sigma_h_m / std::sqrt(static_cast<double>(n));
  if (std::isfinite(fixed_yaw_rad)) {
    out.yaw_sigma_rad = 0;
  } else {
    out.yaw_sigma_rad = f.spread2 > 0 ? sigma_h_m / std::sqrt(f.spread2) : INFINITY;
    if (!(out.yaw_sigma_rad <= config.max_yaw_sigma_rad)) {
      out.reason = "gnss alignment: the antenna has not moved enough for the track to fix the yaw (1-sigma " +
                   std::to_string(out.yaw_sigma_rad * 180.0 / M_PI) + " deg; give the magnetometer's yaw)";
      return out;
    }
  }
  out.valid = true;
  return out;
}

}  // namespace hwr::estimation
