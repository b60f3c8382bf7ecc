#pragma once
// The bundle-adjustment problem (paper eq. 5): keyframe poses T_cam_world and 3D points p_world,
// jointly refined by minimising the reprojection error of their observations (and, for RGB-D
// observations, the error of the measured depth). Plain data plus the residuals and their
// analytic Jacobians, which the solver (ba_solver.hpp) and the tests share.
//
// Residuals (whitened, so the cost is 0.5 * sum rho(|r|^2) exactly as Ceres defines it):
//   reprojection  r = (uv(p_cam) - uv_px) / sigma_px                              (2-vector)
//   depth         r = (z_view(p_cam) - depth_m) / (c * depth_m^2)                 (scalar)
// with p_cam = T_cam_world * p_world and c = BaOptions::depth_sigma_per_m2 (the Kinect-like axial
// noise model sigma_z = c z^2 of Khoshelham & Elberink 2012; sigma uses the *measured* depth so the
// weight is constant during the solve). z_view is the distance along the viewing axis: p_cam.z for
// kPinhole (OpenCV axes), -p_cam.z for kBalRadial (BAL cameras look down -z).
//
// Pose perturbation (the solver's manifold update): left, T_cam_world <- exp(dxi) * T_cam_world with
// dxi = (rho, phi) in core::se3 order ([Sola] arXiv:1812.01537, eq. 172). For a left perturbation
// d p_cam / d dxi = [I, -[p_cam]x] at dxi = 0, independent of the current pose, which keeps the
// Jacobian cheap; the point update is additive, d p_cam / d p_world = R_cam_world.
//
// No cheirality test: a point behind the camera still yields a residual (as in Ceres' functors);
// callers drop such observations (e.g. after a solve).

#include <cmath>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace hwr::estimation {

enum class BaCameraModel {
  kPinhole,    // u = fx*x/z + cx, v = fy*y/z + cy  (our keyframes; OpenCV axes)
  kBalRadial,  // BAL/Snavely: P = R X + t; p = -P/P.z; r = 1 + k1|p|^2 + k2|p|^4; uv = f r p
};

// Per camera, held FIXED by the solver. kPinhole reads fx, fy, cx, cy; kBalRadial reads f, k1, k2
// (uv in pixels relative to the image centre, as BAL files store them).
struct BaIntrinsics {
  double fx = 0, fy = 0, cx = 0, cy = 0;
  double f = 0, k1 = 0, k2 = 0;
};

struct BaCamera {
  Eigen::Isometry3d T_cam_world = Eigen::Isometry3d::Identity();
  BaIntrinsics K;
  bool fixed = false;  // held constant (gauge: the caller fixes the oldest window pose)
};

struct BaPoint {
  Eigen::Vector3d p_world = Eigen::Vector3d::Zero();
  bool fixed = false;  // held constant (marginalised out of the variables)
};

struct BaObservation {
  int camera = 0;
  int point = 0;
  Eigen::Vector2d uv_px = Eigen::Vector2d::Zero();
  double depth_m = 0;  // > 0: RGB-D observation, adds a depth residual
  double sigma_px = 1.0;
};

struct BaProblem {
  BaCameraModel model = BaCameraModel::kPinhole;
  std::vector<BaCamera> cameras;
  std::vector<BaPoint> points;
  std::vector<BaObservation> observations;
};

using BaMatrix26 = Eigen::Matrix<double, 2, 6>;
using BaMatrix23 = Eigen::Matrix<double, 2, 3>;
using BaMatrix16 = Eigen::Matrix<double, 1, 6>;
using BaMatrix13 = Eigen::Matrix<double, 1, 3>;

// uv of a point in camera coordinates and, if d_uv_d_pcam is not null, its derivative. Always
// inlined: the solver's loops call these with constant null / non-null Jacobian pointers, which
// then fold away.
template <BaCameraModel M>
EIGEN_ALWAYS_INLINE Eigen::Vector2d ba_project(const BaIntrinsics& K, const Eigen::Vector3d& p_cam,
                                               BaMatrix23* d_uv_d_pcam = nullptr) {
  if constexpr (M == BaCameraModel::kPinhole) {
    const double iz = 1.0 / p_cam.z();
    const double x = p_cam.x() * iz, y = p_cam.y() * iz;
    if (d_uv_d_pcam != nullptr) {
      *d_uv_d_pcam << K.fx * iz, 0.0, -K.fx * x * iz, 0.0, K.fy * iz, -K.fy * y * iz;
    }
    return {K.fx * x + K.cx, K.fy * y + K.cy};
  } else {
    // Snavely's model: p = -P.xy / P.z, r(p) = 1 + k1 |p|^2 + k2 |p|^4, uv = f r(p) p.
    const double iz = 1.0 / p_cam.z();
    const double px = -p_cam.x() * iz, py = -p_cam.y() * iz;
    const double n2 = px * px + py * py;
    const double r = 1.0 + n2 * (K.k1 + K.k2 * n2);
    if (d_uv_d_pcam != nullptr) {
      // d uv / d p = f (r I + p (dr/dp)^T), dr/dp = (2 k1 + 4 k2 |p|^2) p;
      // d p / d P = [-1/z, 0, x/z^2; 0, -1/z, y/z^2] = iz * [-1, 0, -px; 0, -1, -py].
      const double dr = 2.0 * K.k1 + 4.0 * K.k2 * n2;
      const double a00 = K.f * (r + dr * px * px), a01 = K.f * dr * px * py;
      const double a11 = K.f * (r + dr * py * py);
      *d_uv_d_pcam << -a00 * iz, -a01 * iz, -(a00 * px + a01 * py) * iz,  //
          -a01 * iz, -a11 * iz, -(a01 * px + a11 * py) * iz;
    }
    return {K.f * r * px, K.f * r * py};
  }
}

// Whitened reprojection residual of observation `obs` of p_world by a camera at T_cam_world, with
// optional analytic Jacobians w.r.t. the left pose perturbation dxi = (rho, phi) and the point.
template <BaCameraModel M>
EIGEN_ALWAYS_INLINE Eigen::Vector2d ba_reprojection_residual(const Eigen::Isometry3d& T_cam_world,
                                                             const BaIntrinsics& K,
                                                             const Eigen::Vector3d& p_world,
                                                             const Eigen::Vector2d& uv_px, double sigma_px,
                                                             BaMatrix26* d_r_d_xi = nullptr,
                                                             BaMatrix23* d_r_d_p = nullptr) {
  const Eigen::Matrix3d& R = T_cam_world.linear();
  const Eigen::Vector3d p_cam = R * p_world + T_cam_world.translation();
  const double inv_sigma = 1.0 / sigma_px;
  if (d_r_d_xi == nullptr && d_r_d_p == nullptr) return (ba_project<M>(K, p_cam) - uv_px) * inv_sigma;
  BaMatrix23 A;
  const Eigen::Vector2d uv = ba_project<M>(K, p_cam, &A);
  A *= inv_sigma;
  if (d_r_d_xi != nullptr) {
    // Row a of A times [I, -[p]x]: (a, p x a).
    d_r_d_xi->leftCols<3>() = A;
    for (int i = 0; i < 2; ++i) {
      const Eigen::Vector3d a = A.row(i).transpose();
      d_r_d_xi->block<1, 3>(i, 3) = p_cam.cross(a).transpose();
    }
  }
  if (d_r_d_p != nullptr) *d_r_d_p = A * R;
  return (uv - uv_px) * inv_sigma;
}

// sigma of a depth measurement, the axial noise model sigma_z = c z^2.
inline double ba_depth_sigma_m(double depth_m, double depth_sigma_per_m2) {
  return depth_sigma_per_m2 * depth_m * depth_m;
}

// Whitened depth residual (z_view(p_cam) - depth_m) / sigma_m with optional Jacobians.
template <BaCameraModel M>
EIGEN_ALWAYS_INLINE double ba_depth_residual(const Eigen::Isometry3d& T_cam_world,
                                             const Eigen::Vector3d& p_world, double depth_m, double sigma_m,
                                             BaMatrix16* d_r_d_xi = nullptr, BaMatrix13* d_r_d_p = nullptr) {
  constexpr double kSign = M == BaCameraModel::kPinhole ? 1.0 : -1.0;
  const Eigen::Matrix3d& R = T_cam_world.linear();
  const Eigen::Vector3d p_cam = R * p_world + T_cam_world.translation();
  const double s = kSign / sigma_m;
  if (d_r_d_xi != nullptr) {
    // s e_z^T [I, -[p]x] = s (e_z, p x e_z) = s (0, 0, 1, p.y, -p.x, 0).
    *d_r_d_xi << 0.0, 0.0, s, s * p_cam.y(), -s * p_cam.x(), 0.0;
  }
  if (d_r_d_p != nullptr) *d_r_d_p = s * R.row(2);
  return (kSign * p_cam.z() - depth_m) / sigma_m;
}

// Runtime-dispatched versions for callers that hold a BaCameraModel value.
inline Eigen::Vector2d ba_reprojection_residual(BaCameraModel model, const BaCamera& camera,
                                                const Eigen::Vector3d& p_world, const BaObservation& obs,
                                                BaMatrix26* d_r_d_xi = nullptr,
                                                BaMatrix23* d_r_d_p = nullptr) {
  return model == BaCameraModel::kPinhole
             ? ba_reprojection_residual<BaCameraModel::kPinhole>(camera.T_cam_world, camera.K, p_world,
                                                                 obs.uv_px, obs.sigma_px, d_r_d_xi, d_r_d_p)
             : ba_reprojection_residual<BaCameraModel::kBalRadial>(
                   camera.T_cam_world, camera.K, p_world, obs.uv_px, obs.sigma_px, d_r_d_xi, d_r_d_p);
}

inline double ba_depth_residual(BaCameraModel model, const BaCamera& camera, const Eigen::Vector3d& p_world,
                                const BaObservation& obs, double depth_sigma_per_m2,
                                BaMatrix16* d_r_d_xi = nullptr, BaMatrix13* d_r_d_p = nullptr) {
  const double sigma_m = ba_depth_sigma_m(obs.depth_m, depth_sigma_per_m2);
  return model == BaCameraModel::kPinhole
             ? ba_depth_residual<BaCameraModel::kPinhole>(camera.T_cam_world, p_world, obs.depth_m, sigma_m,
                                                          d_r_d_xi, d_r_d_p)
             : ba_depth_residual<BaCameraModel::kBalRadial>(camera.T_cam_world, p_world, obs.depth_m, sigma_m,
                                                            d_r_d_xi, d_r_d_p);
}

}  // namespace hwr::estimation
