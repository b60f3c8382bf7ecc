#include "hwr/detect/fillet_finder.hpp"

#include <algorithm>
#include <cmath>

#include "hwr/detect/plane_fit.hpp"

namespace hwr::detect {

namespace {

// The q-quantile of v[0..n) (n > 0), reordering v (nearest rank).
double quantile(float* v, int n, double q) {
  const int k = std::clamp(static_cast<int>(std::lround(q * (n - 1))), 0, n - 1);
  std::nth_element(v, v + k, v + n);
  return v[k];
}

// The angle by which two planes miss being perpendicular: asin |n_a . n_b|.
double perpendicular_dev_rad(const Eigen::Vector3d& n_a, const Eigen::Vector3d& n_b) {
  return std::asin(std::min(1.0, std::fabs(n_a.dot(n_b))));
}

// The line where two planes meet: a point on both (the one nearest the camera origin's projection
// onto their span) and the unit direction n_a x n_b. False when they are (nearly) parallel.
bool plane_intersection(const PlaneFit& a, const PlaneFit& b, Eigen::Vector3d* point, Eigen::Vector3d* dir) {
  const double c = a.normal.dot(b.normal);
  const double den = 1.0 - c * c;
  if (den < 1e-6) return false;
  *point = ((a.d - b.d * c) * a.normal + (b.d - a.d * c) * b.normal) / den;
  *dir = a.normal.cross(b.normal).normalized();
  // A fixed orientation (left to right in the image) so that a seam's start and end are stable.
  if (dir->x() < 0) *dir = -*dir;
  return true;
}

// Cells of plane w that have a cell of plane b within `reach` cells (Chebyshev).
int adjacent_cells(const PlaneSegmenter& planes, int b, int w, int reach) {
  const PlaneRegion& rw = planes.plane(w);
  int count = 0;
  for (int cy = rw.min_cy; cy <= rw.max_cy; ++cy) {
    for (int cx = rw.min_cx; cx <= rw.max_cx; ++cx) {
      if (planes.cell_label(cx, cy) != w) continue;
      bool near = false;
      for (int dy = -reach; dy <= reach && !near; ++dy) {
        const int y = cy + dy;
        if (y < 0 || y >= planes.cells_y()) continue;
        for (int dx = -reach; dx <= reach && !near; ++dx) {
          const int x = cx + dx;
          if (x >= 0 && x < planes.cells_x() && planes.cell_label(x, y) == b) near = true;
        }
      }
      count += near ? 1 : 0;
    }
  }
  return count;
}

bool project(const hal::PinholeIntrinsics& K, const Eigen::Vector3d& p_cam, double* u, double* v) {
  if (p_cam.z() <= 1e-3) return false;
  *u = K.fx * p_cam.x() / p_cam.z() + K.cx;
  *v = K.fy * p_cam.y() / p_cam.z() + K.cy;
  return true;
}

bool inside_image(const hal::PinholeIntrinsics& K, double u, double v, double margin_px) {
  return u >= margin_px && v >= margin_px && u <= K.width - 1 - margin_px && v <= K.height - 1 - margin_px;
}

}  // namespace

core::Expected<FilletFinder> FilletFinder::create(const FilletConfig& c, const DepthNoiseModel& noise,
                                                  int max_points) {
  if (max_points < 1) return core::InvalidArgument("fillet finder: max_points must be >= 1");
  if (!(c.max_perpendicular_dev_rad > 0) || !(c.max_base_tilt_rad > 0) || c.adjacency_cells < 1 ||
      c.min_adjacent_cells < 1) {
    return core::InvalidArgument(
        "fillet finder: max_perpendicular_dev_rad, max_base_tilt_rad must be positive; adjacency_cells, "
        "min_adjacent_cells >= 1");
  }
  if (!(c.band_near_m >= 0) || !(c.band_far_m > c.band_near_m) || !(c.band_inlier_sigmas > 0) ||
      c.min_band_points < 3) {
    return core::InvalidArgument(
        "fillet finder: need 0 <= band_near_m < band_far_m, band_inlier_sigmas > 0, min_band_points >= 3");
  }
  if (!(c.min_length_m > 0) || !(c.max_length_m > c.min_length_m) || !(c.min_web_height_m > 0) ||
      !(c.max_web_height_m > c.min_web_height_m) ||
      !(c.web_height_quantile > 0 && c.web_height_quantile <= 1)) {
    return core::InvalidArgument(
        "fillet finder: need 0 < min_length_m < max_length_m, 0 < min_web_height_m < max_web_height_m, "
        "web_height_quantile in (0, 1]");
  }
  if (!(c.free_probe_above_m > 0) || !(c.free_min_jump_m > 0) ||
      !(c.min_free_fraction >= 0 && c.min_free_fraction <= 1) || c.free_probes < 1) {
    return core::InvalidArgument(
        "fillet finder: free_probe_above_m, free_min_jump_m must be positive, min_free_fraction in [0, 1], "
        "free_probes >= 1");
  }
  if (!(c.end_quantile >= 0 && c.end_quantile < 0.5) || c.end_margin_px < 0 || !(c.max_base_width_m > 0) ||
      !(c.box_margin_m >= 0)) {
    return core::InvalidArgument(
        "fillet finder: end_quantile in [0, 0.5), end_margin_px >= 0, max_base_width_m > 0, box_margin_m >= "
        "0");
  }
  FilletFinder f;
  f.config_ = c;
  f.noise_ = noise;
  const size_t n = static_cast<size_t>(max_points);
  f.along_web_.resize(n);
  f.along_base_.resize(n);
  f.heights_.resize(n);
  f.widths_.resize(n);
  return f;
}

int FilletFinder::find(const OrganizedCloud& cloud, const PlaneSegmenter& planes,
                       const Eigen::Vector3d& up_cam, DetectionList* out) {
  const FilletConfig& c = config_;
  const hal::PinholeIntrinsics& K = cloud.intrinsics();
  const int grid_points = cloud.width() * cloud.height();
  if (grid_points > static_cast<int>(along_web_.size())) return 0;  // not the cloud create() was sized for
  const double cos_tilt = std::cos(c.max_base_tilt_rad);
  int appended = 0;
  for (int b = 0; b < planes.plane_count(); ++b) {
    const PlaneFit& base0 = planes.plane(b).fit;
    if (!base0.ok || base0.normal.dot(up_cam) < cos_tilt) continue;
    for (int w = 0; w < planes.plane_count(); ++w) {
      const PlaneFit& web0 = planes.plane(w).fit;
      if (w == b || !web0.ok ||
          perpendicular_dev_rad(base0.normal, web0.normal) > c.max_perpendicular_dev_rad)
        continue;
      if (adjacent_cells(planes, b, w, c.adjacency_cells) < c.min_adjacent_cells) continue;
      // Concave corner: each plate on the camera side of the other (a box's edge is convex).
      if (!(base0.signed_distance(web0.centroid) > 0) || !(web0.signed_distance(base0.centroid) > 0))
        continue;

      // The seam from the plates' bands (header), refitted from the planes' intersection. The first
      // pass takes the bands along the whole line; later ones only within the web's extent along it
      // (less 2 cm at each end): past the plates' ends the base's band would hold the bench, a plate
      // thickness lower.
      PlaneFit base = base0, web = web0;
      Eigen::Vector3d p0, dir;
      if (!plane_intersection(base, web, &p0, &dir)) continue;
      bool fitted = true;
      int web_band_points = 0;
      double t_lo = -1e30, t_hi = 1e30;
      for (int pass = 0; pass < 3 && fitted; ++pass) {
        PlaneMoments m_base, m_web;
        int n_along = 0;
        for (int y = 0; y < cloud.height(); ++y) {
          for (int x = 0; x < cloud.width(); ++x) {
            if (!cloud.valid(x, y)) continue;
            const Eigen::Vector3d p = cloud.point(x, y).cast<double>();
            const double t = dir.dot(p - p0);
            const double s_base = base.signed_distance(p), s_web = web.signed_distance(p);
            const double sigma = noise_.sigma_m(p.z());
            const double tol = c.band_inlier_sigmas * sigma + 0.002;
            const double near = std::max(c.band_near_m, c.band_near_sigmas * sigma);
            const double far = near + (c.band_far_m - c.band_near_m);
            const bool in_web_band = std::fabs(s_web) <= tol && s_base >= near && s_base <= far;
            if (in_web_band) along_web_[n_along++] = static_cast<float>(t);
            if (t < t_lo || t > t_hi) continue;
            if (std::fabs(s_base) <= tol && s_web >= near && s_web <= far) m_base.add(p);
            if (in_web_band) m_web.add(p);
          }
        }
        if (n_along >= c.min_band_points) {
          t_lo = quantile(along_web_.data(), n_along, c.end_quantile) + 0.02;
          t_hi = quantile(along_web_.data(), n_along, 1.0 - c.end_quantile) - 0.02;
        }
        web_band_points = static_cast<int>(m_web.n);
        if (m_base.n < c.min_band_points || m_web.n < c.min_band_points) {
          fitted = false;
          break;
        }
        PlaneFit base1 = fit_plane(m_base), web1 = fit_plane(m_web);
        // A narrow band seen from afar tilts with the noise: where its plane turns from the whole
        // plate's by more than band_max_turn_rad, only its offset is refitted (the whole plate's
        // normal is the better measured one).
        auto offset_only_if_turned = [&](const PlaneFit& whole, const PlaneMoments& m, PlaneFit* band) {
          if (band->ok && std::acos(std::min(1.0, band->normal.dot(whole.normal))) <= c.band_max_turn_rad)
            return;
          *band = whole;
          band->centroid = m.sum / m.n;
          band->d = whole.normal.dot(band->centroid);
        };
        offset_only_if_turned(base0, m_base, &base1);
        offset_only_if_turned(web0, m_web, &web1);
        if (perpendicular_dev_rad(base1.normal, web1.normal) > c.max_perpendicular_dev_rad) {
          fitted = false;
          break;
        }
        base = base1;
        web = web1;
        if (!plane_intersection(base, web, &p0, &dir)) fitted = false;
      }
      if (!fitted) continue;

      // Extent along the seam: where the web's band and the base's band overlap.
      int n_web = 0, n_base = 0;
      for (int y = 0; y < cloud.height(); ++y) {
        for (int x = 0; x < cloud.width(); ++x) {
          if (!cloud.valid(x, y)) continue;
          const Eigen::Vector3d p = cloud.point(x, y).cast<double>();
          const double s_base = base.signed_distance(p), s_web = web.signed_distance(p);
          const double sigma = noise_.sigma_m(p.z());
          const double tol = c.band_inlier_sigmas * sigma + 0.002;
          const double near = std::max(c.band_near_m, c.band_near_sigmas * sigma);
          const double far = near + (c.band_far_m - c.band_near_m);
          const float t = static_cast<float>(dir.dot(p - p0));
          if (std::fabs(s_web) <= tol && s_base >= near && s_base <= far) along_web_[n_web++] = t;
          if (std::fabs(s_base) <= tol && s_web >= near && s_web <= far) along_base_[n_base++] = t;
        }
      }
      if (n_web < c.min_band_points || n_base < c.min_band_points) continue;
      double t0 = std::max(quantile(along_web_.data(), n_web, c.end_quantile),
                           quantile(along_base_.data(), n_base, c.end_quantile));
      double t1 = std::min(quantile(along_web_.data(), n_web, 1.0 - c.end_quantile),
                           quantile(along_base_.data(), n_base, 1.0 - c.end_quantile));
      // Points spread evenly along [a, b] put the q-quantile q (b - a) inside each end.
      const double inset = c.end_quantile / (1.0 - 2.0 * c.end_quantile) * (t1 - t0);
      t0 -= inset;
      t1 += inset;
      const double length = t1 - t0;
      if (!(length >= c.min_length_m && length <= c.max_length_m)) continue;

      // The web's height above the base and the base's width, over the seam's extent.
      int n_h = 0, n_w = 0;
      for (int y = 0; y < cloud.height(); ++y) {
        for (int x = 0; x < cloud.width(); ++x) {
          if (!cloud.valid(x, y)) continue;
          const Eigen::Vector3d p = cloud.point(x, y).cast<double>();
          const double t = dir.dot(p - p0);
          if (t < t0 || t > t1) continue;
          const double s_base = base.signed_distance(p), s_web = web.signed_distance(p);
          const double sigma = noise_.sigma_m(p.z());
          const double tol = c.band_inlier_sigmas * sigma + 0.002;
          const double near = std::max(c.band_near_m, c.band_near_sigmas * sigma);
          if (std::fabs(s_web) <= tol && s_base >= near) heights_[n_h++] = static_cast<float>(s_base);
          if (std::fabs(s_base) <= tol && s_web >= near && s_web <= c.max_base_width_m)
            widths_[n_w++] = static_cast<float>(s_web);
        }
      }
      if (n_h < c.min_band_points) continue;
      const double height = quantile(heights_.data(), n_h, c.web_height_quantile);
      if (!(height >= c.min_web_height_m && height <= c.max_web_height_m)) continue;
      const double width = n_w > 0 ? quantile(widths_.data(), n_w, c.web_height_quantile) : c.band_far_m;

      // Free top edge: probes above the web's top, in its plane, must see farther or nothing.
      Eigen::Vector3d up_web = base.normal - base.normal.dot(web.normal) * web.normal;
      if (up_web.norm() < 1e-6) continue;
      up_web.normalize();
      int observed = 0, free = 0;
      for (int k = 0; k < c.free_probes; ++k) {
        const double t = t0 + (k + 0.5) / c.free_probes * length;
        const Eigen::Vector3d q = p0 + t * dir + (height + c.free_probe_above_m) * up_web;
        double u, v;
        if (!project(K, q, &u, &v) || !inside_image(K, u, v, 0.0)) continue;
        const int gx = std::clamp(static_cast<int>(std::lround(u / cloud.stride_px())), 0, cloud.width() - 1);
        const int gy =
            std::clamp(static_cast<int>(std::lround(v / cloud.stride_px())), 0, cloud.height() - 1);
        ++observed;
        // Behind a box's front face its top recedes: the ray through q meets a surface at the edge's
        // height after probe_above / sin(elevation) along it. Past a free plate's edge it meets the
        // support or the background, much farther: the jump must be twice the box top's.
        const Eigen::Vector3d ray = q.normalized();
        const double box_top_run_m = c.free_probe_above_m / std::max(0.05, std::fabs(ray.dot(up_web)));
        const double min_jump_m = std::max(c.free_min_jump_m, 2.0 * box_top_run_m * ray.z());
        if (!cloud.valid(gx, gy) || cloud.point(gx, gy).z() > q.z() + min_jump_m) ++free;
      }
      if (observed * 4 < c.free_probes || free < c.min_free_fraction * observed) continue;

      Detection d;
      d.source = DetectionSource::kGeometry;
      d.kind = SeamKind::kFillet;
      d.seam_cam[0] = p0 + t0 * dir;
      d.seam_cam[1] = p0 + t1 * dir;
      for (int e = 0; e < 2; ++e) {
        double u, v;
        d.end_observed[e] = project(K, d.seam_cam[e], &u, &v) && inside_image(K, u, v, c.end_margin_px);
      }
      d.plate_normal_cam = {base.normal, web.normal};
      // Box: x along the seam, z the base's normal; the base lies on the web's camera side.
      Eigen::Vector3d across = web.normal - web.normal.dot(base.normal) * base.normal;
      across.normalize();
      Eigen::Matrix3d R;
      R.col(0) = dir;
      R.col(2) = (base.normal - base.normal.dot(dir) * dir).normalized();
      R.col(1) = R.col(2).cross(R.col(0));
      d.T_cam_box.linear() = R;
      d.T_cam_box.translation() =
          0.5 * (d.seam_cam[0] + d.seam_cam[1]) + 0.5 * width * across + 0.5 * height * R.col(2);
      d.half_size_m = Eigen::Vector3d(0.5 * length, 0.5 * width, 0.5 * height) +
                      Eigen::Vector3d::Constant(c.box_margin_m);
      // The box's image rectangle: its corners in front of the camera, clipped to the image.
      double u_min = 1e30, v_min = 1e30, u_max = -1e30, v_max = -1e30;
      for (int i = 0; i < 8; ++i) {
        const Eigen::Vector3d corner_box((i & 4 ? 1 : -1) * d.half_size_m.x(),
                                         (i & 2 ? 1 : -1) * d.half_size_m.y(),
                                         (i & 1 ? 1 : -1) * d.half_size_m.z());
        double u, v;
        if (!project(K, d.T_cam_box * corner_box, &u, &v)) continue;
        u_min = std::min(u_min, u);
        v_min = std::min(v_min, v);
        u_max = std::max(u_max, u);
        v_max = std::max(v_max, v);
      }
      if (u_max >= u_min) {
        u_min = std::clamp(u_min, 0.0, K.width - 1.0);
        u_max = std::clamp(u_max, 0.0, K.width - 1.0);
        v_min = std::clamp(v_min, 0.0, K.height - 1.0);
        v_max = std::clamp(v_max, 0.0, K.height - 1.0);
        d.box_px = cv::Rect2f(static_cast<float>(u_min), static_cast<float>(v_min),
                              static_cast<float>(u_max - u_min), static_cast<float>(v_max - v_min));
      }
      const double dev = perpendicular_dev_rad(base.normal, web.normal);
      d.confidence = static_cast<float>((1.0 - dev / c.max_perpendicular_dev_rad) *
                                        std::min(1.0, web_band_points / 400.0) * std::min(1.0, length / 0.2));
      if (!out->push(d)) return appended;
      ++appended;
    }
  }
  return appended;
}

}  // namespace hwr::detect
