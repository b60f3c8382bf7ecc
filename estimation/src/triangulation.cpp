#include "hwr/estimation/triangulation.hpp"

#include <cmath>

#include <Eigen/SVD>

namespace hwr::estimation {
namespace {

Eigen::Vector3d normalised(const hal::PinholeIntrinsics& K, const Eigen::Vector2d& uv) {
  return {(uv.x() - K.cx) / K.fx, (uv.y() - K.cy) / K.fy, 1.0};
}

double reprojection_px(const Eigen::Isometry3d& T_cam_world, const hal::PinholeIntrinsics& K,
                       const Eigen::Vector3d& p_world, const Eigen::Vector2d& uv) {
  const Eigen::Vector3d p = T_cam_world * p_world;
  const Eigen::Vector2d proj(K.fx * p.x() / p.z() + K.cx, K.fy * p.y() / p.z() + K.cy);
  return (proj - uv).norm();
}

}  // namespace

const char* to_string(TriangulationStatus status) {
  switch (status) {
    case TriangulationStatus::kOk:
      return "ok";
    case TriangulationStatus::kLowParallax:
      return "low parallax";
    case TriangulationStatus::kBehindCamera:
      return "depth out of range";
    case TriangulationStatus::kLargeReprojection:
      return "large reprojection error";
    case TriangulationStatus::kDegenerate:
      return "degenerate";
  }
  return "unknown";
}

TriangulationStatus triangulate_two_view(const Eigen::Isometry3d& T_cam0_world,
                                         const Eigen::Isometry3d& T_cam1_world,
                                         const hal::PinholeIntrinsics& K0, const hal::PinholeIntrinsics& K1,
                                         const Eigen::Vector2d& uv0_px, const Eigen::Vector2d& uv1_px,
                                         const TriangulationConfig& cfg, Eigen::Vector3d* p_world) {
  if (!K0.valid() || !K1.valid()) return TriangulationStatus::kDegenerate;
  const Eigen::Vector3d x0 = normalised(K0, uv0_px), x1 = normalised(K1, uv1_px);
  // Parallax: angle between the two viewing rays in the world frame.
  const Eigen::Vector3d ray0 = T_cam0_world.linear().transpose() * x0;
  const Eigen::Vector3d ray1 = T_cam1_world.linear().transpose() * x1;
  const double cos_parallax = ray0.dot(ray1) / (ray0.norm() * ray1.norm());
  if (!(cos_parallax < std::cos(cfg.min_parallax_deg * M_PI / 180.0)))
    return TriangulationStatus::kLowParallax;

  // DLT, eq. (4) / H&Z (12.2): x × (P X) = 0 gives two rows per view, P = [R | t] (normalised).
  const Eigen::Matrix<double, 3, 4> P0 = T_cam0_world.matrix().topRows<3>();
  const Eigen::Matrix<double, 3, 4> P1 = T_cam1_world.matrix().topRows<3>();
  Eigen::Matrix4d A;
  A.row(0) = x0.x() * P0.row(2) - P0.row(0);
  A.row(1) = x0.y() * P0.row(2) - P0.row(1);
  A.row(2) = x1.x() * P1.row(2) - P1.row(0);
  A.row(3) = x1.y() * P1.row(2) - P1.row(1);
  // Row scaling does not change the null vector and evens out the conditioning.
  for (int r = 0; r < 4; ++r) {
    const double nr = A.row(r).norm();
    if (nr > 0) A.row(r) /= nr;
  }
  const Eigen::JacobiSVD<Eigen::Matrix4d> svd(A, Eigen::ComputeFullV);
  const Eigen::Vector4d X = svd.matrixV().col(3);
  if (!X.allFinite() || std::abs(X(3)) < 1e-12 * X.head<3>().norm()) return TriangulationStatus::kDegenerate;
  const Eigen::Vector3d p = X.head<3>() / X(3);
  if (!p.allFinite()) return TriangulationStatus::kDegenerate;
  *p_world = p;

  const double z0 = (T_cam0_world * p).z(), z1 = (T_cam1_world * p).z();
  if (!(z0 >= cfg.min_depth_m && z0 <= cfg.max_depth_m && z1 >= cfg.min_depth_m && z1 <= cfg.max_depth_m)) {
    return TriangulationStatus::kBehindCamera;
  }
  if (reprojection_px(T_cam0_world, K0, p, uv0_px) > cfg.max_reproj_px ||
      reprojection_px(T_cam1_world, K1, p, uv1_px) > cfg.max_reproj_px) {
    return TriangulationStatus::kLargeReprojection;
  }
  return TriangulationStatus::kOk;
}

}  // namespace hwr::estimation
