#include "hwr/detect/plane_fit.hpp"

#include <algorithm>
#include <cmath>

#include <Eigen/Eigenvalues>

namespace hwr::detect {
namespace {

// Collinear (or coincident) points: the scatter's two smallest eigenvalues vanish up to the
// cancellation error of sum_outer / n - c c^T, ~1e-16 |c|^2. The second-smallest must exceed 1e-10
// of the largest (collinear points: the line's spread) and 1e-12 |c|^2 (coincident points: all ~0;
// at 3.5 m that is a spread of 1e-5 m, far below any real plane).
constexpr double kDegenerateRatio = 1e-10;
constexpr double kDegenerateCancellation = 1e-12;

}  // namespace

void PlaneMoments::add(const Eigen::Vector3d& p) {
  n += 1.0;
  sum += p;
  sum_outer.noalias() += p * p.transpose();
}

void PlaneMoments::merge(const PlaneMoments& other) {
  n += other.n;
  sum += other.sum;
  sum_outer += other.sum_outer;
}

PlaneFit fit_plane(const PlaneMoments& m) {
  PlaneFit fit;
  if (m.n < 3.0) return fit;
  fit.centroid = m.sum / m.n;
  // Scatter (covariance) of the points about their centroid: E[p p^T] - c c^T.
  Eigen::Matrix3d scatter = m.sum_outer / m.n - fit.centroid * fit.centroid.transpose();
  scatter = 0.5 * (scatter + scatter.transpose());
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(scatter);
  if (eig.info() != Eigen::Success) return fit;
  const Eigen::Vector3d& ev = eig.eigenvalues();  // ascending
  if (!(ev(1) > kDegenerateRatio * ev(2) + kDegenerateCancellation * fit.centroid.squaredNorm())) return fit;
  // Total least squares: the normal is the direction of least spread, ev(0) the mean squared
  // distance to the plane.
  fit.normal = eig.eigenvectors().col(0).normalized();
  if (fit.normal.dot(fit.centroid) > 0.0) fit.normal = -fit.normal;
  fit.d = fit.normal.dot(fit.centroid);
  fit.rms_m = std::sqrt(std::max(0.0, ev(0)));
  fit.ok = true;
  return fit;
}

}  // namespace hwr::detect
