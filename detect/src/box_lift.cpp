#include "hwr/detect/box_lift.hpp"

#include <algorithm>
#include <cmath>
#include <string>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <opencv2/core.hpp>

#include "hwr/detect/plane_fit.hpp"

namespace hwr::detect {

namespace {

constexpr double kMadToSigma = 1.4826;    // MAD of a normal distribution = 0.6745 sigma
constexpr double kPlaneSlackM = 0.002;    // as the plane segmentation's merge test: 3 sigma(z) + 2 mm
constexpr uint64_t kRansacSeed = 0x5eed;  // fixed: the same keyframe gives the same box

bool project(const hal::PinholeIntrinsics& K, const Eigen::Vector3d& p_cam, double* u, double* v) {
  if (p_cam.z() <= 1e-6) return false;
  *u = K.fx * p_cam.x() / p_cam.z() + K.cx;
  *v = K.fy * p_cam.y() / p_cam.z() + K.cy;
  return true;
}

// A unit vector perpendicular to n (unit).
Eigen::Vector3d any_perpendicular(const Eigen::Vector3d& n) {
  const Eigen::Vector3d a = std::fabs(n.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY();
  return n.cross(a).normalized();
}

}  // namespace

BoxLifter::BoxLifter(const BoxLiftConfig& config, const hal::PinholeIntrinsics& K) : config_(config), K_(K) {
  const size_t most = static_cast<size_t>((K.width + config.stride_px - 1) / config.stride_px) *
                      static_cast<size_t>((K.height + config.stride_px - 1) / config.stride_px);
  points_.resize(most);
  scratch_.resize(most);
  inlier_.resize(most);
}

core::Expected<BoxLifter> BoxLifter::create(const BoxLiftConfig& config, const hal::PinholeIntrinsics& K) {
  if (!K.valid()) {
    return core::InvalidArgument("box lift: invalid intrinsics (width " + std::to_string(K.width) +
                                 ", height " + std::to_string(K.height) + ", fx " + std::to_string(K.fx) +
                                 ", fy " + std::to_string(K.fy) + "): all must be > 0");
  }
  if (config.stride_px < 1) return core::InvalidArgument("box lift: stride_px must be >= 1");
  if (!(config.min_depth_m >= 0.0f) || !(config.max_depth_m > config.min_depth_m)) {
    return core::InvalidArgument("box lift: depth range needs 0 <= min_depth_m < max_depth_m");
  }
  if (config.min_points < 3) return core::InvalidArgument("box lift: min_points must be >= 3");
  if (!(config.band_mads >= 0) || !(config.band_min_m > 0)) {
    return core::InvalidArgument("box lift: needs band_mads >= 0 and band_min_m > 0");
  }
  if (config.ransac_iterations < 1 || !(config.plane_inlier_sigmas > 0)) {
    return core::InvalidArgument("box lift: needs ransac_iterations >= 1 and plane_inlier_sigmas > 0");
  }
  if (!(config.extent_quantile >= 0 && config.extent_quantile < 0.5) || !(config.min_half_size_m >= 0)) {
    return core::InvalidArgument("box lift: needs 0 <= extent_quantile < 0.5 and min_half_size_m >= 0");
  }
  return BoxLifter(config, K);
}

double BoxLifter::quantile(std::vector<double>* values, int n, double q) {
  const auto k = static_cast<std::ptrdiff_t>(std::lround(q * (n - 1)));
  std::nth_element(values->begin(), values->begin() + k, values->begin() + n);
  return (*values)[static_cast<size_t>(k)];
}

double BoxLifter::median(std::vector<double>* values, int n) { return quantile(values, n, 0.5); }

core::Expected<LiftOutcome> BoxLifter::lift(const cv::Mat& depth_m, const cv::Rect2f& box_px, Detection* d) {
  if (depth_m.type() != CV_32FC1 || depth_m.cols != K_.width || depth_m.rows != K_.height) {
    return core::InvalidArgument("box lift: depth must be CV_32FC1 of " + std::to_string(K_.width) + "x" +
                                 std::to_string(K_.height) + ", got type " + std::to_string(depth_m.type()) +
                                 " " + std::to_string(depth_m.cols) + "x" + std::to_string(depth_m.rows));
  }
  const BoxLiftConfig& c = config_;
  // Pixel i's centre is at i + 0.5 in the box's continuous coordinates: i in [ceil(x0 - 0.5), x1 - 0.5).
  if (!(std::isfinite(box_px.x) && std::isfinite(box_px.y) && std::isfinite(box_px.width) &&
        std::isfinite(box_px.height)))
    return LiftOutcome::kTooFewDepth;  // no pixel lies in a box without finite edges
  // Clamped in double before the conversion: a box from the wire may lie far outside int's range.
  auto pixel = [](double edge, int size) {
    return static_cast<int>(std::clamp(std::ceil(edge - 0.5), 0.0, static_cast<double>(size)));
  };
  const int u0 = pixel(box_px.x, K_.width), v0 = pixel(box_px.y, K_.height);
  const int u1 = pixel(static_cast<double>(box_px.x) + box_px.width, K_.width);
  const int v1 = pixel(static_cast<double>(box_px.y) + box_px.height, K_.height);

  // 1. Valid depth, back-projected (eq. 3).
  int n = 0;
  for (int v = v0; v < v1; v += c.stride_px) {
    const float* row = depth_m.ptr<float>(v);
    const double ray_y = (v - K_.cy) / K_.fy;
    for (int u = u0; u < u1; u += c.stride_px) {
      const float z = row[u];
      if (!std::isfinite(z) || z < c.min_depth_m || z > c.max_depth_m) continue;
      points_[static_cast<size_t>(n)] = Eigen::Vector3d((u - K_.cx) / K_.fx * z, ray_y * z, z);
      scratch_[static_cast<size_t>(n)] = z;
      ++n;
    }
  }
  if (n < c.min_points) return LiftOutcome::kTooFewDepth;

  // 2. The depth band around the median.
  const double median_z = median(&scratch_, n);
  for (int i = 0; i < n; ++i)
    scratch_[static_cast<size_t>(i)] = std::fabs(points_[static_cast<size_t>(i)].z() - median_z);
  const double band_m = std::max(c.band_min_m, c.band_mads * kMadToSigma * median(&scratch_, n));
  int kept = 0;
  for (int i = 0; i < n; ++i) {
    if (std::fabs(points_[static_cast<size_t>(i)].z() - median_z) <= band_m) {
      points_[static_cast<size_t>(kept++)] = points_[static_cast<size_t>(i)];
    }
  }
  n = kept;
  if (n < c.min_points) return LiftOutcome::kTooFewDepth;

  // 3. The dominant plane: RANSAC on 3-point samples, then the inliers' least-squares plane.
  const double inlier_m = c.plane_inlier_sigmas * c.noise.sigma_m(median_z) + kPlaneSlackM;
  cv::RNG rng(kRansacSeed);
  int best_count = 0;
  Eigen::Vector3d best_normal = Eigen::Vector3d::UnitZ();
  double best_d = 0;
  for (int it = 0; it < c.ransac_iterations; ++it) {
    const Eigen::Vector3d& a = points_[static_cast<size_t>(rng.uniform(0, n))];
    const Eigen::Vector3d& b = points_[static_cast<size_t>(rng.uniform(0, n))];
    const Eigen::Vector3d& p = points_[static_cast<size_t>(rng.uniform(0, n))];
    const Eigen::Vector3d cross = (b - a).cross(p - a);
    const double norm = cross.norm();
    if (norm < 1e-12) continue;  // coincident or collinear sample
    const Eigen::Vector3d normal = cross / norm;
    const double dist = normal.dot(a);
    int count = 0;
    for (int i = 0; i < n; ++i)
      count += std::fabs(normal.dot(points_[static_cast<size_t>(i)]) - dist) <= inlier_m;
    if (count > best_count) best_count = count, best_normal = normal, best_d = dist;
  }
  if (best_count < c.min_points) return LiftOutcome::kNoPlane;
  PlaneMoments moments;
  for (int i = 0; i < n; ++i) {
    const bool in = std::fabs(best_normal.dot(points_[static_cast<size_t>(i)]) - best_d) <= inlier_m;
    inlier_[static_cast<size_t>(i)] = in;
    if (in) moments.add(points_[static_cast<size_t>(i)]);
  }
  const PlaneFit plane = fit_plane(moments);
  if (!plane.ok) return LiftOutcome::kNoPlane;

  // 4. The box's axes: z the plane's normal, x the inliers' principal direction in the plane.
  const Eigen::Vector3d z_axis = plane.normal;
  const Eigen::Vector3d e1 = any_perpendicular(z_axis), e2 = z_axis.cross(e1);
  Eigen::Matrix2d scatter = Eigen::Matrix2d::Zero();
  for (int i = 0; i < n; ++i) {
    if (!inlier_[static_cast<size_t>(i)]) continue;
    const Eigen::Vector3d q = points_[static_cast<size_t>(i)] - plane.centroid;
    const Eigen::Vector2d w(e1.dot(q), e2.dot(q));
    scatter += w * w.transpose();
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig(scatter);
  const Eigen::Vector2d major = eig.eigenvectors().col(1);  // eigenvalues ascending
  Eigen::Vector3d x_axis = (major.x() * e1 + major.y() * e2).normalized();
  if (x_axis.x() < 0 || (std::fabs(x_axis.x()) < 1e-9 && x_axis.y() < 0)) x_axis = -x_axis;
  Eigen::Matrix3d R;
  R.col(0) = x_axis;
  R.col(1) = z_axis.cross(x_axis);
  R.col(2) = z_axis;

  // The extent along each axis from robust quantiles of all the band's points.
  Eigen::Vector3d lo, hi;
  for (int axis = 0; axis < 3; ++axis) {
    for (int i = 0; i < n; ++i) {
      scratch_[static_cast<size_t>(i)] = R.col(axis).dot(points_[static_cast<size_t>(i)] - plane.centroid);
    }
    lo[axis] = quantile(&scratch_, n, c.extent_quantile);
    hi[axis] = quantile(&scratch_, n, 1.0 - c.extent_quantile);
  }
  d->T_cam_box.linear() = R;
  d->T_cam_box.translation() = plane.centroid + R * (0.5 * (lo + hi));
  d->half_size_m = (0.5 * (hi - lo)).cwiseMax(c.min_half_size_m);
  const Eigen::Vector3d centre = d->T_cam_box.translation();
  d->seam_cam = {centre - d->half_size_m.x() * x_axis, centre + d->half_size_m.x() * x_axis};
  d->end_observed = {false, false};
  d->plate_normal_cam = {z_axis, z_axis};

  // The box's image rectangle: its corners in front of the camera, clipped to the image.
  double u_min = 1e30, v_min = 1e30, u_max = -1e30, v_max = -1e30;
  for (int i = 0; i < 8; ++i) {
    const Eigen::Vector3d corner_box((i & 4 ? 1 : -1) * d->half_size_m.x(),
                                     (i & 2 ? 1 : -1) * d->half_size_m.y(),
                                     (i & 1 ? 1 : -1) * d->half_size_m.z());
    double u, v;
    if (!project(K_, d->T_cam_box * corner_box, &u, &v)) continue;
    u_min = std::min(u_min, u), v_min = std::min(v_min, v);
    u_max = std::max(u_max, u), v_max = std::max(v_max, v);
  }
  d->box_px = cv::Rect2f();
  if (u_max >= u_min) {
    u_min = std::clamp(u_min, 0.0, K_.width - 1.0), u_max = std::clamp(u_max, 0.0, K_.width - 1.0);
    v_min = std::clamp(v_min, 0.0, K_.height - 1.0), v_max = std::clamp(v_max, 0.0, K_.height - 1.0);
    d->box_px = cv::Rect2f(static_cast<float>(u_min), static_cast<float>(v_min),
                           static_cast<float>(u_max - u_min), static_cast<float>(v_max - v_min));
  }
  return LiftOutcome::kLifted;
}

}  // namespace hwr::detect
