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

FilletFinder::BandLimits FilletFinder::band_limits(double z_m) const {
  const FilletConfig& c = config_;
  const double sigma = noise_.sigma_m(z_m);
  BandLimits b;
  b.tol_m = c.band_inlier_sigmas * sigma + 0.002;
  b.near_m = std::max(c.band_near_m, c.band_near_sigmas * sigma);
  b.far_m = b.near_m + (c.band_far_m - c.band_near_m);
  return b;
}

// The seam from the plates' bands (header), refitted from the planes' intersection. The first pass
// takes the bands along the whole line; later ones only within the web's extent along it (less 2 cm
// at each end): past the plates' ends the base's band would hold the bench, a plate thickness lower.
bool FilletFinder::fit_seam_line(const OrganizedCloud& cloud, const PlaneFit& base0, const PlaneFit& web0,
                                 Seam* seam) {
  const FilletConfig& c = config_;
  seam->base = base0;
  seam->web = web0;
  if (!plane_intersection(seam->base, seam->web, &seam->p0, &seam->dir)) return false;
  double t_lo = -1e30, t_hi = 1e30;
  for (int pass = 0; pass < 3; ++pass) {
    PlaneMoments m_base, m_web;
    int n_along = 0;
    for (int y = 0; y < cloud.height(); ++y) {
      for (int x = 0; x < cloud.width(); ++x) {
        if (!cloud.valid(x, y)) continue;
        const Eigen::Vector3d p = cloud.point(x, y).cast<double>();
        const double t = seam->dir.dot(p - seam->p0);
        const double s_base = seam->base.signed_distance(p), s_web = seam->web.signed_distance(p);
        const BandLimits band = band_limits(p.z());
        const bool in_web_band =
            std::fabs(s_web) <= band.tol_m && s_base >= band.near_m && s_base <= band.far_m;
        if (in_web_band) along_web_[n_along++] = static_cast<float>(t);
        if (t < t_lo || t > t_hi) continue;
        if (std::fabs(s_base) <= band.tol_m && s_web >= band.near_m && s_web <= band.far_m) m_base.add(p);
        if (in_web_band) m_web.add(p);
      }
    }
    if (n_along >= c.min_band_points) {
      t_lo = quantile(along_web_.data(), n_along, c.end_quantile) + 0.02;
      t_hi = quantile(along_web_.data(), n_along, 1.0 - c.end_quantile) - 0.02;
    }
    seam->web_band_points = static_cast<int>(m_web.n);
    if (m_base.n < c.min_band_points || m_web.n < c.min_band_points) return false;
    PlaneFit base1 = fit_plane(m_base), web1 = fit_plane(m_web);
    // A narrow band seen from afar tilts with the noise: where its plane turns from the whole plate's
    // by more than band_max_turn_rad, only its offset is refitted (the whole plate's normal is the
    // better measured one).
    auto offset_only_if_turned = [&](const PlaneFit& whole, const PlaneMoments& m, PlaneFit* band) {
      if (band->ok && std::acos(std::min(1.0, band->normal.dot(whole.normal))) <= c.band_max_turn_rad) return;
      *band = whole;
      band->centroid = m.sum / m.n;
      band->d = whole.normal.dot(band->centroid);
    };
    offset_only_if_turned(base0, m_base, &base1);
    offset_only_if_turned(web0, m_web, &web1);
    if (perpendicular_dev_rad(base1.normal, web1.normal) > c.max_perpendicular_dev_rad) return false;
    seam->base = base1;
    seam->web = web1;
    if (!plane_intersection(seam->base, seam->web, &seam->p0, &seam->dir)) return false;
  }
  return true;
}

// Extent along the seam: where the web's band and the base's band overlap, less the quantile's inset.
bool FilletFinder::fit_seam_extent(const OrganizedCloud& cloud, Seam* seam) {
  const FilletConfig& c = config_;
  int n_web = 0, n_base = 0;
  for (int y = 0; y < cloud.height(); ++y) {
    for (int x = 0; x < cloud.width(); ++x) {
      if (!cloud.valid(x, y)) continue;
      const Eigen::Vector3d p = cloud.point(x, y).cast<double>();
      const double s_base = seam->base.signed_distance(p), s_web = seam->web.signed_distance(p);
      const BandLimits band = band_limits(p.z());
      const float t = static_cast<float>(seam->dir.dot(p - seam->p0));
      if (std::fabs(s_web) <= band.tol_m && s_base >= band.near_m && s_base <= band.far_m)
        along_web_[n_web++] = t;
      if (std::fabs(s_base) <= band.tol_m && s_web >= band.near_m && s_web <= band.far_m)
        along_base_[n_base++] = t;
    }
  }
  if (n_web < c.min_band_points || n_base < c.min_band_points) return false;
  seam->t0 = std::max(quantile(along_web_.data(), n_web, c.end_quantile),
                      quantile(along_base_.data(), n_base, c.end_quantile));
  seam->t1 = std::min(quantile(along_web_.data(), n_web, 1.0 - c.end_quantile),
                      quantile(along_base_.data(), n_base, 1.0 - c.end_quantile));
  // Points spread evenly along [a, b] put the q-quantile q (b - a) inside each end.
  const double inset = c.end_quantile / (1.0 - 2.0 * c.end_quantile) * (seam->t1 - seam->t0);
  seam->t0 -= inset;
  seam->t1 += inset;
  const double length = seam->t1 - seam->t0;
  return length >= c.min_length_m && length <= c.max_length_m;
}

// The web's height above the base and the base's width, over the seam's extent.
bool FilletFinder::fit_plate_sizes(const OrganizedCloud& cloud, Seam* seam) {
  const FilletConfig& c = config_;
  int n_h = 0, n_w = 0;
  for (int y = 0; y < cloud.height(); ++y) {
    for (int x = 0; x < cloud.width(); ++x) {
      if (!cloud.valid(x, y)) continue;
      const Eigen::Vector3d p = cloud.point(x, y).cast<double>();
      const double t = seam->dir.dot(p - seam->p0);
      if (t < seam->t0 || t > seam->t1) continue;
      const double s_base = seam->base.signed_distance(p), s_web = seam->web.signed_distance(p);
      const BandLimits band = band_limits(p.z());
      if (std::fabs(s_web) <= band.tol_m && s_base >= band.near_m)
        heights_[n_h++] = static_cast<float>(s_base);
      if (std::fabs(s_base) <= band.tol_m && s_web >= band.near_m && s_web <= c.max_base_width_m)
        widths_[n_w++] = static_cast<float>(s_web);
    }
  }
  if (n_h < c.min_band_points) return false;
  seam->height_m = quantile(heights_.data(), n_h, c.web_height_quantile);
  seam->width_m = n_w > 0 ? quantile(widths_.data(), n_w, c.web_height_quantile) : c.band_far_m;
  return seam->height_m >= c.min_web_height_m && seam->height_m <= c.max_web_height_m;
}

// Free top edge: probes above the web's top, in its plane, must see farther or nothing.
bool FilletFinder::top_edge_free(const OrganizedCloud& cloud, const Seam& seam) const {
  const FilletConfig& c = config_;
  const hal::PinholeIntrinsics& K = cloud.intrinsics();
  Eigen::Vector3d up_web = seam.base.normal - seam.base.normal.dot(seam.web.normal) * seam.web.normal;
  if (up_web.norm() < 1e-6) return false;
  up_web.normalize();
  const double length = seam.t1 - seam.t0;
  int observed = 0, free = 0;
  for (int k = 0; k < c.free_probes; ++k) {
    const double t = seam.t0 + (k + 0.5) / c.free_probes * length;
    const Eigen::Vector3d q = seam.p0 + t * seam.dir + (seam.height_m + c.free_probe_above_m) * up_web;
    double u, v;
    if (!project(K, q, &u, &v) || !inside_image(K, u, v, 0.0)) continue;
    const int gx = std::clamp(static_cast<int>(std::lround(u / cloud.stride_px())), 0, cloud.width() - 1);
    const int gy = std::clamp(static_cast<int>(std::lround(v / cloud.stride_px())), 0, cloud.height() - 1);
    ++observed;
    // Behind a box's front face its top recedes: the ray through q meets a surface at the edge's
    // height after probe_above / sin(elevation) along it. Past a free plate's edge it meets the
    // support or the background, much farther: the jump must be twice the box top's.
    const Eigen::Vector3d ray = q.normalized();
    const double box_top_run_m = c.free_probe_above_m / std::max(0.05, std::fabs(ray.dot(up_web)));
    const double min_jump_m = std::max(c.free_min_jump_m, 2.0 * box_top_run_m * ray.z());
    if (!cloud.valid(gx, gy) || cloud.point(gx, gy).z() > q.z() + min_jump_m) ++free;
  }
  return observed * 4 >= c.free_probes && free >= c.min_free_fraction * observed;
}

Detection FilletFinder::to_detection(const hal::PinholeIntrinsics& K, const Seam& seam) const {
  const FilletConfig& c = config_;
  const double length = seam.t1 - seam.t0;
  Detection d;
  d.source = DetectionSource::kGeometry;
  d.kind = SeamKind::kFillet;
  d.seam_cam[0] = seam.p0 + seam.t0 * seam.dir;
  d.seam_cam[1] = seam.p0 + seam.t1 * seam.dir;
  for (int e = 0; e < 2; ++e) {
    double u, v;
    d.end_observed[e] = project(K, d.seam_cam[e], &u, &v) && inside_image(K, u, v, c.end_margin_px);
  }
  d.plate_normal_cam = {seam.base.normal, seam.web.normal};
  // Box: x along the seam, z the base's normal; the base lies on the web's camera side.
  Eigen::Vector3d across = seam.web.normal - seam.web.normal.dot(seam.base.normal) * seam.base.normal;
  across.normalize();
  Eigen::Matrix3d R;
  R.col(0) = seam.dir;
  R.col(2) = (seam.base.normal - seam.base.normal.dot(seam.dir) * seam.dir).normalized();
  R.col(1) = R.col(2).cross(R.col(0));
  d.T_cam_box.linear() = R;
  d.T_cam_box.translation() =
      0.5 * (d.seam_cam[0] + d.seam_cam[1]) + 0.5 * seam.width_m * across + 0.5 * seam.height_m * R.col(2);
  d.half_size_m = Eigen::Vector3d(0.5 * length, 0.5 * seam.width_m, 0.5 * seam.height_m) +
                  Eigen::Vector3d::Constant(c.box_margin_m);
  d.box_px = box_image_rect(K, d.T_cam_box, d.half_size_m);
  const double dev = perpendicular_dev_rad(seam.base.normal, seam.web.normal);
  d.confidence =
      static_cast<float>((1.0 - dev / c.max_perpendicular_dev_rad) *
                         std::min(1.0, seam.web_band_points / 400.0) * std::min(1.0, length / 0.2));
  return d;
}

int FilletFinder::find(const OrganizedCloud& cloud, const PlaneSegmenter& planes,
                       const Eigen::Vector3d& up_cam, DetectionList* out) {
  const FilletConfig& c = config_;
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
      Seam seam;
      if (!fit_seam_line(cloud, base0, web0, &seam) || !fit_seam_extent(cloud, &seam) ||
          !fit_plate_sizes(cloud, &seam) || !top_edge_free(cloud, seam))
        continue;
      if (!out->push(to_detection(cloud.intrinsics(), seam))) return appended;
      ++appended;
    }
  }
  return appended;
}

}  // namespace hwr::detect
