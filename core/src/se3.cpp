#include "hwr/core/se3.hpp"

#include <cstdio>

#include <Eigen/SVD>

#include "hwr/core/so3.hpp"

namespace hwr::core {

Eigen::Isometry3d se3_exp(const Vector6d& xi) {
  const Eigen::Vector3d rho = xi.head<3>();
  const Eigen::Vector3d phi = xi.tail<3>();
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = so3_exp(phi);
  T.translation() = so3_left_jacobian(phi) * rho;
  return T;
}

Vector6d se3_log(const Eigen::Isometry3d& T) {
  const Eigen::Vector3d phi = so3_log(T.linear());
  Vector6d xi;
  xi.head<3>() = so3_left_jacobian_inverse(phi) * T.translation();
  xi.tail<3>() = phi;
  return xi;
}

Eigen::Isometry3d se3_interpolate(const Eigen::Isometry3d& T0, const Eigen::Isometry3d& T1, double alpha) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = so3_interpolate(T0.linear(), T1.linear(), alpha);
  T.translation() = (1.0 - alpha) * T0.translation() + alpha * T1.translation();
  return T;
}

Eigen::Matrix3d orthonormalize(const Eigen::Matrix3d& R) {
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(R, Eigen::ComputeFullU | Eigen::ComputeFullV);
  const Eigen::Matrix3d U = svd.matrixU();
  const Eigen::Matrix3d V = svd.matrixV();
  Eigen::Matrix3d D = Eigen::Matrix3d::Identity();
  D(2, 2) = (U * V.transpose()).determinant() < 0.0 ? -1.0 : 1.0;
  return U * D * V.transpose();
}

std::string rigid_transform_problem(const Eigen::Isometry3d& T) {
  if (!T.matrix().allFinite()) return "has a non-finite entry";
  const Eigen::Matrix3d R = T.linear();
  const double orthonormality = (R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
  if (orthonormality > 1e-6) {
    char buf[96];
    std::snprintf(buf, sizeof(buf), "is not rigid: |R^T R - I| = %.3g (at most 1e-6)", orthonormality);
    return buf;
  }
  if (R.determinant() < 0) return "is not rigid: det R = -1 (a reflection)";
  if (T.matrix().row(3) != Eigen::RowVector4d(0, 0, 0, 1)) return "is not rigid: last row is not 0 0 0 1";
  return "";
}

}  // namespace hwr::core
