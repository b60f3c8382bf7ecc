#pragma once
// SE(3) helpers on Eigen::Isometry3d. A twist xi is the 6-vector (rho, phi): rho (first three, m)
// is the translational part, phi (last three, rad) the rotation vector, the order Sophus and
// [Sola] (arXiv:1812.01537) use. Note rho is not the translation of exp(xi) unless phi = 0:
// t = Jl(phi) rho, [Sola] eq. (172).

#include <string>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace hwr::core {

using Vector6d = Eigen::Matrix<double, 6, 1>;

// exp(xi) = [exp(phi), Jl(phi) rho; 0, 1]. [Sola] eq. (172).
Eigen::Isometry3d se3_exp(const Vector6d& xi);
// Inverse of se3_exp: phi = log(R), rho = Jl(phi)^-1 t. |phi| in [0, pi].
Vector6d se3_log(const Eigen::Isometry3d& T);

// Pose interpolation: rotation along the SO(3) geodesic (so3_interpolate), translation on the
// straight line t0 + alpha (t1 - t0). This is not the SE(3) geodesic (a screw motion); it is the
// usual choice for poses between image timestamps because the position moves at constant velocity
// independently of how the body turns. Exact at alpha = 0 and 1.
Eigen::Isometry3d se3_interpolate(const Eigen::Isometry3d& T0, const Eigen::Isometry3d& T1, double alpha);

// The rotation nearest to R in the Frobenius norm (polar decomposition through the SVD,
// U diag(1, 1, det(U V^T)) V^T). Removes the drift of repeated products; R must be near a rotation
// (det > 0) for the result to be meaningful.
Eigen::Matrix3d orthonormalize(const Eigen::Matrix3d& R);

// Empty when T is a finite rigid transform (rotation orthonormal within 1e-6, determinant +1, last
// row 0 0 0 1); else what is wrong, as a phrase ("is not rigid: ..."), for error messages.
std::string rigid_transform_problem(const Eigen::Isometry3d& T);

}  // namespace hwr::core
