#pragma once
// SO(3) on plain Eigen types: rotation vectors omega = theta * axis (rad), rotation matrices R and
// unit quaternions q with R = q.toRotationMatrix(). Conventions follow Sola, Deray, Atchuthan,
// "A micro Lie theory for state estimation in robotics" (arXiv:1812.01537), cited as [Sola].
//
// Invariants:
//  - so3_exp(w) is a rotation for every finite w.
//  - so3_log(R) returns |w| in [0, pi]. At theta = pi exactly (R symmetric), w and -w give the
//    same R; the result is the one whose largest-magnitude component is positive.
//  - Both functions are accurate to machine precision for theta -> 0 (Taylor series) and for
//    theta -> pi (axis from the symmetric part of R, where sin(theta) carries no information).

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace hwr::core {

// [w]x: hat(w) * v == w.cross(v). [Sola] eq. (9).
Eigen::Matrix3d hat(const Eigen::Vector3d& w);
// Inverse of hat for a skew-symmetric matrix; for a general M it returns vee of its skew part.
Eigen::Vector3d vee(const Eigen::Matrix3d& M);

// Rodrigues: R = I + sin(t)/t [w]x + (1 - cos(t))/t^2 [w]x^2, t = |w|. [Sola] eq. (77).
Eigen::Matrix3d so3_exp(const Eigen::Vector3d& omega);
// Inverse of so3_exp with |w| in [0, pi]. R must be a rotation (orthonormal, det +1).
Eigen::Vector3d so3_log(const Eigen::Matrix3d& R);

// Right Jacobian Jr(w): exp(w + d) ~= exp(w) exp(Jr(w) d) for small d. [Sola] eq. (143).
Eigen::Matrix3d so3_right_jacobian(const Eigen::Vector3d& omega);
// Jr(w)^-1: log(exp(w) exp(d)) ~= w + Jr(w)^-1 d. [Sola] eq. (144). Singular at |w| = 2 pi;
// valid for the |w| <= pi that so3_log returns.
Eigen::Matrix3d so3_right_jacobian_inverse(const Eigen::Vector3d& omega);
// Left Jacobian Jl(w) = Jr(-w): exp(w + d) ~= exp(Jl(w) d) exp(w). [Sola] eq. (145). It is also the
// V matrix of se3_exp.
Eigen::Matrix3d so3_left_jacobian(const Eigen::Vector3d& omega);
Eigen::Matrix3d so3_left_jacobian_inverse(const Eigen::Vector3d& omega);

// Geodesic interpolation R0 * exp(alpha * log(R0^T R1)): constant angular rate from R0
// (alpha = 0) to R1 (alpha = 1) along the shorter arc. Replaces the paper's eq. (2), which
// interpolates R linearly and so leaves SO(3) between the endpoints.
Eigen::Matrix3d so3_interpolate(const Eigen::Matrix3d& R0, const Eigen::Matrix3d& R1, double alpha);

// Quaternion versions. quat_exp returns a unit quaternion with w >= 0 for |omega| <= pi.
Eigen::Quaterniond quat_exp(const Eigen::Vector3d& omega);
// Uses the double cover: q and -q give the same w with |w| <= pi. q must be unit norm.
Eigen::Vector3d quat_log(const Eigen::Quaterniond& q);
// Same geodesic as so3_interpolate (equal to slerp along the shorter arc).
Eigen::Quaterniond quat_interpolate(const Eigen::Quaterniond& q0, const Eigen::Quaterniond& q1, double alpha);

}  // namespace hwr::core
