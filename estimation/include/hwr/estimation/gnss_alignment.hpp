#pragma once
// The pose of a run's world frame in the local ENU frame of a geodetic origin, from GNSS fixes
// (issue #6 item 2: "when available, translation from GNSS (geodetic -> local ENU)"). The world
// frame is gravity-aligned (ARCHITECTURE.md), so T_enu_world has 4 degrees of freedom: a yaw psi
// about the vertical (R_enu_world = Rz(psi), as in mag_heading.hpp) and a translation t.
//
// Given pairs (p_world_k: the antenna position from the estimator, p_enu_k: the fix moved into
// ENU, core/geodetic.hpp), the fit minimises sum_k |Rz(psi) p_world_k + t - p_enu_k|^2, every fix
// weighing the same (one accuracy sigma_h, sigma_v for the run):
//   horizontal: the closed-form 2D rotation of the centred point sets (Kabsch/Umeyama in the plane,
//   psi = atan2(sum (x_w y_e - y_w x_e), sum (x_w x_e + y_w y_e)) over centred coordinates),
//   then t_xy from the centroids; vertical: t_z = mean of z_e - z_w.
// With a known yaw (the magnetometer's, fixed_yaw) only t is fitted. The pair with the largest
// horizontal residual over outlier_sigmas sigma_h is dropped and the fit repeated (multipath, a bad
// fix), one pair at a time, until none is over. The yaw is observable only when the antenna moved: its
// 1-sigma is sigma_h / sqrt(sum |p_world,xy - centroid|^2) (small-angle, per-axis noise sigma_h); a fit whose
// yaw sigma exceeds max_yaw_sigma_rad is not valid unless the yaw was given.
//
// A position in ENU then maps into a run's world frame as p_world = T_enu_world^-1 p_enu, and a
// current GNSS fix into the prior run's frame through T_prior_enu = T_enu_world_prior^-1.

#include <string>
#include <vector>

#include <Eigen/Geometry>

namespace hwr::estimation {

struct GnssAlignmentConfig {
  double outlier_sigmas = 4.0;
  double max_yaw_sigma_rad = 0.05;  // ~3 deg: below this the track fixes the yaw
  int min_pairs = 3;
};

struct GnssAlignment {
  bool valid = false;
  std::string reason;  // why not, when !valid
  Eigen::Isometry3d T_enu_world = Eigen::Isometry3d::Identity();
  double yaw_rad = 0;             // psi of R_enu_world = Rz(psi)
  double yaw_sigma_rad = 0;       // 0 when the yaw was given
  double horizontal_sigma_m = 0;  // 1-sigma of t_xy: sigma_h / sqrt(pairs used)
  double rms_horizontal_m = 0;    // residual of the pairs used
  int pairs_used = 0, pairs_dropped = 0;
};

// sigma_h_m, sigma_v_m: the fixes' 1-sigma accuracies (> 0). fixed_yaw_rad: a known psi (e.g. the
// magnetometer's), or NaN to fit it. Pairs with a non-finite coordinate are dropped.
GnssAlignment fit_T_enu_world(const std::vector<Eigen::Vector3d>& p_world,
                              const std::vector<Eigen::Vector3d>& p_enu, double sigma_h_m, double sigma_v_m,
                              double fixed_yaw_rad, const GnssAlignmentConfig& config = {});

}  // namespace hwr::estimation
