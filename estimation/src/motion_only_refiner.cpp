#include "hwr/estimation/motion_only_refiner.hpp"

#include <algorithm>
#include <cmath>

#include <Eigen/Cholesky>

#include "hwr/core/se3.hpp"

namespace hwr::estimation {
namespace {

using Matrix6d = Eigen::Matrix<double, 6, 6>;
using Vector6d = Eigen::Matrix<double, 6, 1>;
constexpr int kMaxOctaves = 32;

// Whitened residual of one correspondence at a pose, and optionally its Jacobian w.r.t. the left
// perturbation dxi = (rho, phi): d(exp(dxi) p)/d(dxi) = [I, -[p]x] at dxi = 0.
struct Residual {
  Eigen::Vector3d r = Eigen::Vector3d::Zero();  // (du, dv, ddepth) / sigma
  Eigen::Matrix<double, 3, 6> J = Eigen::Matrix<double, 3, 6>::Zero();
  int dim = 2;            // 3 with the depth residual
  double pixel_err2 = 0;  // unwhitened squared pixel error
  bool valid = false;     // in front of the camera
};

Residual evaluate(const Correspondence& c, const hal::PinholeIntrinsics& K, const Eigen::Matrix3d& R,
                  const Eigen::Vector3d& t, const RefineConfig& cfg, const double* inv_sigma_of_octave,
                  bool with_jacobian) {
  Residual res;
  const Eigen::Vector3d p = R * c.p_world + t;
  if (!(p.z() > 1e-6)) return res;
  res.valid = true;
  const double inv_z = 1.0 / p.z();
  const double u = K.fx * p.x() * inv_z + K.cx, v = K.fy * p.y() * inv_z + K.cy;
  const double inv_sigma = inv_sigma_of_octave[std::clamp(c.octave, 0, kMaxOctaves - 1)];
  const double du = u - c.uv_px.x(), dv = v - c.uv_px.y();
  res.pixel_err2 = du * du + dv * dv;
  res.r.x() = du * inv_sigma;
  res.r.y() = dv * inv_sigma;
  const bool depth = cfg.use_depth && c.depth_m > 0;
  double inv_sigma_d = 0;
  if (depth) {
    // Depth residual (z - d) / (c d^2): structured-light depth noise grows with d^2
    // (Khoshelham & Elberink 2012); sigma from the measured depth so it is constant in the solve.
    inv_sigma_d = 1.0 / (cfg.depth_sigma_per_m2 * c.depth_m * c.depth_m);
    res.r.z() = (p.z() - c.depth_m) * inv_sigma_d;
    res.dim = 3;
  }
  if (!with_jacobian) return res;
  Eigen::Matrix<double, 3, 6> dp;
  dp.leftCols<3>().setIdentity();
  dp.rightCols<3>() << 0, p.z(), -p.y(), -p.z(), 0, p.x(), p.y(), -p.x(), 0;  // -[p]x
  Eigen::Matrix<double, 2, 3> dproj;
  dproj << K.fx * inv_z, 0, -K.fx * p.x() * inv_z * inv_z, 0, K.fy * inv_z, -K.fy * p.y() * inv_z * inv_z;
  res.J.topRows<2>() = inv_sigma * dproj * dp;
  if (depth) res.J.row(2) = inv_sigma_d * dp.row(2);
  return res;
}

// Huber (Huber 1964) on the whitened residual norm e: cost and IRLS weight.
inline void huber(double chi2, double delta, double* cost, double* weight) {
  const double e = std::sqrt(chi2);
  if (e <= delta) {
    *cost = chi2;
    *weight = 1.0;
  } else {
    *cost = 2.0 * delta * e - delta * delta;
    *weight = delta / e;
  }
}

Eigen::Isometry3d make_pose(const Eigen::Matrix3d& R, const Eigen::Vector3d& t) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = R;
  T.translation() = t;
  return T;
}

double chi2_of(const Residual& r) { return r.dim == 3 ? r.r.squaredNorm() : r.r.head<2>().squaredNorm(); }

}  // namespace

MotionOnlyRefiner::MotionOnlyRefiner(int max_correspondences)
    : max_correspondences_(std::max(max_correspondences, 0)) {}

RefineResult MotionOnlyRefiner::refine(const Correspondence* c, int n, const hal::PinholeIntrinsics& K,
                                       const Eigen::Isometry3d& T_init_cam_world, const RefineConfig& cfg,
                                       uint8_t* inlier_mask) {
  RefineResult result;
  result.T_cam_world = T_init_cam_world;
  const int m = std::min(n, max_correspondences_);
  for (int i = 0; i < n; ++i) inlier_mask[i] = i < m ? 1 : 0;
  if (m < 3 || !K.valid()) {
    for (int i = 0; i < n; ++i) inlier_mask[i] = 0;
    return result;
  }
  // Pixel sigma of octave k: scale_factor^k (the keypoint was detected at that pyramid scale).
  double inv_sigma[kMaxOctaves];
  for (int k = 0; k < kMaxOctaves; ++k) inv_sigma[k] = 1.0 / std::pow(cfg.scale_factor, k);
  Eigen::Matrix3d R = T_init_cam_world.linear();
  Eigen::Vector3d t = T_init_cam_world.translation();

  // Robust cost and normal equations over the current inliers.
  auto linearize = [&](const Eigen::Matrix3d& Rx, const Eigen::Vector3d& tx, Matrix6d* H, Vector6d* b) {
    double cost = 0;
    if (H) H->setZero();
    if (b) b->setZero();
    for (int i = 0; i < m; ++i) {
      if (!inlier_mask[i]) continue;
      const Residual r = evaluate(c[i], K, Rx, tx, cfg, inv_sigma, H != nullptr);
      if (!r.valid) {
        cost += cfg.chi2_3dof * 4;  // behind the camera: a flat penalty keeps LM from going there
        continue;
      }
      double ci, w;
      huber(chi2_of(r), r.dim == 3 ? cfg.huber_3dof : cfg.huber_px, &ci, &w);
      cost += ci;
      if (H) {
        if (r.dim == 3) {
          H->noalias() += w * r.J.transpose() * r.J;
          b->noalias() += w * r.J.transpose() * r.r;
        } else {
          H->noalias() += w * r.J.topRows<2>().transpose() * r.J.topRows<2>();
          b->noalias() += w * r.J.topRows<2>().transpose() * r.r.head<2>();
        }
      }
    }
    return cost;
  };

  int included = m;
  for (int round = 0; round < std::max(cfg.rounds, 1); ++round) {
    double lambda = -1;
    Matrix6d H;
    Vector6d b;
    double cost = linearize(R, t, &H, &b);
    for (int it = 0; it < cfg.iterations_per_round; ++it) {
      ++result.iterations;
      if (lambda < 0) lambda = 1e-4 * std::max(H.diagonal().maxCoeff(), 1e-12);
      bool accepted = false;
      for (int attempt = 0; attempt < 8 && !accepted; ++attempt) {
        Matrix6d A = H;
        A.diagonal().array() += lambda;
        const Vector6d dx = A.ldlt().solve(-b);
        if (!dx.allFinite()) {
          lambda *= 10;
          continue;
        }
        const Eigen::Isometry3d T_new = core::se3_exp(dx) * make_pose(R, t);
        const double new_cost = linearize(T_new.linear(), T_new.translation(), nullptr, nullptr);
        if (new_cost <= cost) {
          R = T_new.linear();
          t = T_new.translation();
          lambda = std::max(lambda / 3.0, 1e-12);
          accepted = true;
          // Converged: a step under a micrometre / microradian, or no relative cost change left.
          if (dx.squaredNorm() < 1e-12 || cost - new_cost <= 1e-9 * cost) it = cfg.iterations_per_round;
        } else {
          lambda *= 4.0;
        }
      }
      if (!accepted || it >= cfg.iterations_per_round) break;
      cost = linearize(R, t, &H, &b);
    }
    // Re-classify every correspondence at the new pose (ORB-SLAM: outliers may come back).
    included = 0;
    for (int i = 0; i < m; ++i) {
      const Residual r = evaluate(c[i], K, R, t, cfg, inv_sigma, false);
      const bool in = r.valid && chi2_of(r) <= (r.dim == 3 ? cfg.chi2_3dof : cfg.chi2_px2);
      inlier_mask[i] = in ? 1 : 0;
      included += in ? 1 : 0;
    }
    if (included < 5) break;
  }

  // Covariance: inverse of the Gauss-Newton information J^T J of the inliers' whitened residuals.
  Matrix6d H = Matrix6d::Zero();
  double err2 = 0;
  for (int i = 0; i < m; ++i) {
    if (!inlier_mask[i]) continue;
    const Residual r = evaluate(c[i], K, R, t, cfg, inv_sigma, true);
    err2 += r.pixel_err2;
    if (r.dim == 3) {
      H.noalias() += r.J.transpose() * r.J;
    } else {
      H.noalias() += r.J.topRows<2>().transpose() * r.J.topRows<2>();
    }
  }
  result.T_cam_world.linear() = R;
  result.T_cam_world.translation() = t;
  result.inliers = included;
  result.rms_px = included > 0 ? std::sqrt(err2 / included) : 0;
  const Eigen::LDLT<Matrix6d> ldlt(H);
  const bool invertible = included >= 3 && ldlt.info() == Eigen::Success && ldlt.isPositive() &&
                          ldlt.vectorD().minCoeff() > 1e-12 * std::max(ldlt.vectorD().maxCoeff(), 1e-300);
  if (invertible) result.covariance = ldlt.solve(Matrix6d::Identity());
  result.ok = invertible && included >= cfg.min_inliers && R.allFinite() && t.allFinite();
  return result;
}

}  // namespace hwr::estimation
