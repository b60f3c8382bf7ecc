#pragma once
// Least-squares planes from accumulated moments: the plane through the centroid whose normal is the
// eigenvector of the scatter matrix with the smallest eigenvalue (total least squares). Moments add
// and merge, so a region's plane is refitted from its parts' sums without revisiting points.

#include <Eigen/Core>

namespace hwr::detect {

struct PlaneMoments {
  double n = 0;
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  Eigen::Matrix3d sum_outer = Eigen::Matrix3d::Zero();  // sum of p p^T
  void add(const Eigen::Vector3d& p);
  void merge(const PlaneMoments& other);
};

struct PlaneFit {
  bool ok = false;                                    // >= 3 points, not collinear
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();  // unit; faces the origin (the camera)
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  double d = 0;      // normal . p = d on the plane
  double rms_m = 0;  // RMS distance of the points to the plane
  double signed_distance(const Eigen::Vector3d& p) const { return normal.dot(p) - d; }
};

// The plane of the moments, its normal turned to face the frame's origin (normal . centroid <= 0).
PlaneFit fit_plane(const PlaneMoments& m);

}  // namespace hwr::detect
