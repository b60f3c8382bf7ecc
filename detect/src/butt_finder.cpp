#include "hwr/detect/butt_finder.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/Geometry>

namespace hwr::detect {

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr int kMaxSegments = 8;
constexpr double kInf = std::numeric_limits<double>::infinity();

bool project(const hal::PinholeIntrinsics& K, const Eigen::Vector3d& p_cam, Eigen::Vector2d* px) {
  if (p_cam.z() <= 1e-3) return false;
  *px = Eigen::Vector2d(K.fx * p_cam.x() / p_cam.z() + K.cx, K.fy * p_cam.y() / p_cam.z() + K.cy);
  return true;
}

bool inside_image(const hal::PinholeIntrinsics& K, const Eigen::Vector2d& px, double margin_px) {
  return px.x() >= margin_px && px.y() >= margin_px && px.x() <= K.width - 1 - margin_px &&
         px.y() <= K.height - 1 - margin_px;
}

// > 0 when o -> a -> b turns left (counter-clockwise).
float cross2(const Eigen::Vector2f& o, const Eigen::Vector2f& a, const Eigen::Vector2f& b) {
  return (a.x() - o.x()) * (b.y() - o.y()) - (a.y() - o.y()) * (b.x() - o.x());
}

// The median of v[0..n) (n > 0; the upper one for even n), reordering v.
double median(double* v, int n) {
  std::nth_element(v, v + n / 2, v + n);
  return v[n / 2];
}

// Luma (ITU-R BT.601) of a BGR pixel.
float luma(const cv::Mat& bgr, int u, int v) {
  const uint8_t* p = bgr.ptr<uint8_t>(v) + 3 * u;
  return 0.114f * p[0] + 0.587f * p[1] + 0.299f * p[2];
}

// One cue's significance over the parts of a line (header): the parts' z summed over sqrt(parts)
// without the largest; -inf unless at least three parts have pixels and all but one reach min_z_part.
struct PartSum {
  double sum = 0, max = -kInf;
  int valid = 0, low = 0;
  void add(double z, double min_z_part) {
    sum += z;
    max = std::max(max, z);
    ++valid;
    low += z < min_z_part ? 1 : 0;
  }
  double z() const { return valid >= 3 && low <= 1 ? (sum - max) / std::sqrt(valid - 1.0) : -kInf; }
};

}  // namespace

core::Expected<ButtFinder> ButtFinder::create(const ButtConfig& c, const DepthNoiseModel& noise,
                                              const hal::PinholeIntrinsics& K) {
  if (!K.valid()) return core::InvalidArgument("butt finder: invalid intrinsics");
  if (!(c.direction_range_rad >= 0) || !(c.direction_step_rad > 0)) {
    return core::InvalidArgument("butt finder: need direction_range_rad >= 0, direction_step_rad > 0");
  }
  if (!(c.bin_px > 0) || !(c.centre_px >= c.bin_px) || !(c.side_gap_px >= 0) || !(c.side_px >= c.bin_px) ||
      c.max_bins < 16 || c.segments < 3 || c.segments > kMaxSegments || c.min_window_samples < 1) {
    return core::InvalidArgument(
        "butt finder: need bin_px > 0, centre_px and side_px >= bin_px, side_gap_px >= 0, max_bins >= 16, "
        "segments in [3, 8], min_window_samples >= 1");
  }
  if (!(c.dark_ratio > 0 && c.dark_ratio < 1) || !(c.dark_offset_px >= 1) || !(c.min_segment_z >= 0) ||
      !(c.min_plate_width_m > 0) || !(c.min_z > 0) || !(c.support_z > 0 && c.support_z <= c.min_z) ||
      !(c.max_depth_residual_m > 0)) {
    return core::InvalidArgument(
        "butt finder: need dark_ratio in (0, 1), dark_offset_px >= 1, min_segment_z >= 0, support_z in "
        "(0, min_z], and min_plate_width_m, min_z, max_depth_residual_m positive");
  }
  if (!(c.min_length_m > 0) || !(c.max_length_m > c.min_length_m) || !(c.end_band_near_m >= 0) ||
      !(c.end_band_far_m > c.end_band_near_m) || !(c.end_search_m > 0) || c.end_margin_px < 0 ||
      !(c.box_margin_m >= 0)) {
    return core::InvalidArgument(
        "butt finder: need 0 < min_length_m < max_length_m, 0 <= end_band_near_m < end_band_far_m, "
        "end_search_m > 0, end_margin_px >= 0, box_margin_m >= 0");
  }
  ButtFinder f;
  f.config_ = c;
  f.noise_ = noise;
  f.K_ = K;
  const size_t pixels = static_cast<size_t>(K.width) * static_cast<size_t>(K.height);
  f.samples_.resize(pixels);
  f.points_.resize(pixels);
  f.hull_.resize(pixels + 1);
  const size_t bins = static_cast<size_t>(c.max_bins) + 1;
  const size_t profile = bins * static_cast<size_t>(c.segments);
  f.n_.resize(profile);
  f.dark_.resize(profile);
  f.depth_sum_.resize(profile);
  f.depth_n_.resize(profile);
  f.scratch_.resize(bins);
  f.end_sum_.resize(2 * bins);
  f.end_n_.resize(2 * bins);
  return f;
}

// Where the ray of pixel (u, v), r = ((u - cx) / fx, (v - cy) / fy, 1), meets the plane: lambda r with
// lambda = (n . origin) / (n . r), the plane's depth there; *a its plane coordinates.
bool ButtFinder::on_plane(const Plane2d& plane, double u, double v, Eigen::Vector2f* a,
                          double* depth_m) const {
  const Eigen::Vector3d ray((u - K_.cx) / K_.fx, (v - K_.cy) / K_.fy, 1.0);
  const double den = plane.normal.dot(ray);
  if (std::fabs(den) < 1e-9) return false;
  *depth_m = plane.normal.dot(plane.origin) / den;
  if (!(*depth_m > 0)) return false;
  const Eigen::Vector3d q = *depth_m * ray - plane.origin;
  *a = Eigen::Vector2f(static_cast<float>(plane.e1.dot(q)), static_cast<float>(plane.e2.dot(q)));
  return true;
}

// The image displacement (pixels per metre) of a step along `along` from the plane's origin.
Eigen::Vector2d ButtFinder::image_direction(const Plane2d& plane, const Eigen::Vector3d& along) const {
  const double eps = 0.01;
  Eigen::Vector2d o, a;
  if (!project(K_, plane.origin, &o) || !project(K_, plane.origin + eps * along, &a))
    return Eigen::Vector2d::Zero();
  return (a - o) / eps;
}

// The region's inner border points (an inner point with a 4-neighbour that is not) on the plane.
int ButtFinder::collect_border(const OrganizedCloud& cloud, const RaisedRegionFinder& raised, int region,
                               const Plane2d& plane) {
  const RaisedRegion& r = raised.region(region);
  auto in_region = [&](int x, int y) {
    return x >= 0 && y >= 0 && x < cloud.width() && y < cloud.height() &&
           raised.region_label(x, y) == region && raised.inner(x, y);
  };
  const int s = cloud.stride_px();
  int n = 0;
  for (int y = r.min_y; y <= r.max_y; ++y) {
    for (int x = r.min_x; x <= r.max_x; ++x) {
      if (!in_region(x, y) ||
          (in_region(x - 1, y) && in_region(x + 1, y) && in_region(x, y - 1) && in_region(x, y + 1)))
        continue;
      Eigen::Vector2f a;
      double depth;
      if (on_plane(plane, x * s, y * s, &a, &depth)) points_[static_cast<size_t>(n++)] = a;
    }
  }
  return n;
}

// Convex hull of points_[0..n) (Andrew's monotone chain), counter-clockwise into hull_; its size.
int ButtFinder::hull(int n) {
  if (n < 3) return 0;
  std::sort(points_.begin(), points_.begin() + n, [](const Eigen::Vector2f& a, const Eigen::Vector2f& b) {
    return a.x() < b.x() || (a.x() == b.x() && a.y() < b.y());
  });
  int k = 0;
  for (int i = 0; i < n; ++i) {  // lower hull
    while (k >= 2 && cross2(hull_[static_cast<size_t>(k - 2)], hull_[static_cast<size_t>(k - 1)],
                            points_[static_cast<size_t>(i)]) <= 0)
      --k;
    hull_[static_cast<size_t>(k++)] = points_[static_cast<size_t>(i)];
  }
  for (int i = n - 2, lower = k + 1; i >= 0; --i) {  // upper hull
    while (k >= lower && cross2(hull_[static_cast<size_t>(k - 2)], hull_[static_cast<size_t>(k - 1)],
                                points_[static_cast<size_t>(i)]) <= 0)
      --k;
    hull_[static_cast<size_t>(k++)] = points_[static_cast<size_t>(i)];
  }
  return k - 1;  // the last point repeats the first
}

// The seam directions to try: the axes of the region's smallest-area enclosing rectangle (one of its
// sides lies along a hull edge: Freeman and Shapira 1975). Angles in the plane basis; false for a
// degenerate hull.
bool ButtFinder::rectangle_axes(int n_hull, double* phi) const {
  double best_area = kInf;
  for (int i = 0; i < n_hull; ++i) {
    const Eigen::Vector2f e = hull_[static_cast<size_t>((i + 1) % n_hull)] - hull_[static_cast<size_t>(i)];
    const float length = e.norm();
    if (length < 1e-6f) continue;
    const Eigen::Vector2f u = e / length, v(-u.y(), u.x());
    float u_lo = 1e30f, u_hi = -1e30f, v_lo = 1e30f, v_hi = -1e30f;
    for (int k = 0; k < n_hull; ++k) {
      const Eigen::Vector2f& p = hull_[static_cast<size_t>(k)];
      u_lo = std::min(u_lo, u.dot(p));
      u_hi = std::max(u_hi, u.dot(p));
      v_lo = std::min(v_lo, v.dot(p));
      v_hi = std::max(v_hi, v.dot(p));
    }
    const double area = static_cast<double>(u_hi - u_lo) * (v_hi - v_lo);
    if (area < best_area) {
      best_area = area;
      phi[0] = std::atan2(u.y(), u.x());
      phi[1] = phi[0] + 0.5 * kPi;
    }
  }
  return std::isfinite(best_area);
}

// The region's inner pixels as samples (a grid point stands for the stride x stride pixels from it),
// dark across each of the two directions phi[0], phi[1] (their image normals at the region's centre).
int ButtFinder::collect_samples(const OrganizedCloud& cloud, const RaisedRegionFinder& raised, int region,
                                const Plane2d& plane, const double* phi, const cv::Mat* bgr,
                                const cv::Mat& depth_m) {
  const ButtConfig& c = config_;
  const RaisedRegion& r = raised.region(region);
  const int s = cloud.stride_px();
  const float max_residual = static_cast<float>(c.max_depth_residual_m);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float ratio = static_cast<float>(c.dark_ratio);
  int du[2] = {0, 0}, dv[2] = {0, 0};
  for (int i = 0; i < 2; ++i) {
    const Eigen::Vector2d dir =
        image_direction(plane, std::cos(phi[i]) * plane.e1 + std::sin(phi[i]) * plane.e2).normalized();
    du[i] = static_cast<int>(std::lround(-dir.y() * c.dark_offset_px));
    dv[i] = static_cast<int>(std::lround(dir.x() * c.dark_offset_px));
  }
  int n = 0;
  for (int y = r.min_y; y <= r.max_y; ++y) {
    for (int x = r.min_x; x <= r.max_x; ++x) {
      if (raised.region_label(x, y) != region || !raised.inner(x, y)) continue;
      for (int v = y * s; v < std::min((y + 1) * s, K_.height); ++v) {
        const float* depth_row = depth_m.ptr<float>(v);
        for (int u = x * s; u < std::min((x + 1) * s, K_.width); ++u) {
          Eigen::Vector2f a;
          double plane_depth;
          if (!on_plane(plane, u, v, &a, &plane_depth)) continue;
          Sample& sample = samples_[static_cast<size_t>(n++)];
          sample.a1 = a.x();
          sample.a2 = a.y();
          const float z = depth_row[u];
          sample.residual = std::isfinite(z) && z > 0.0f
                                ? std::clamp(z - static_cast<float>(plane_depth), -max_residual, max_residual)
                                : nan;
          sample.dark = 0;
          if (bgr == nullptr) continue;
          const float grey = luma(*bgr, u, v);
          for (int i = 0; i < 2; ++i) {
            const int u0 = u - du[i], v0 = v - dv[i], u1 = u + du[i], v1 = v + dv[i];
            if (std::min(std::min(u0, u1), std::min(v0, v1)) < 0 || std::max(u0, u1) >= K_.width ||
                std::max(v0, v1) >= K_.height)
              continue;
            if (grey < ratio * std::min(luma(*bgr, u0, v0), luma(*bgr, u1, v1))) sample.dark |= 1u << i;
          }
        }
      }
    }
  }
  return n;
}

// The profiles across the directions phi_c +- direction_range_rad (header); *best keeps the most
// significant line.
void ButtFinder::sweep_direction(const Plane2d& plane, int n_samples, int n_hull, double phi_c, int axis,
                                 bool use_dark, double sigma_z_m, Line* best) {
  const ButtConfig& c = config_;
  const Eigen::Vector3d along_c = std::cos(phi_c) * plane.e1 + std::sin(phi_c) * plane.e2;
  const Eigen::Vector3d across_c = -std::sin(phi_c) * plane.e1 + std::cos(phi_c) * plane.e2;
  // Metres on the plane per image pixel across the line's image.
  const Eigen::Vector2d line_px = image_direction(plane, along_c),
                        across_px = image_direction(plane, across_c);
  const double px_per_m =
      std::fabs(line_px.normalized().x() * across_px.y() - line_px.normalized().y() * across_px.x());
  if (!(px_per_m > 0) || !std::isfinite(px_per_m)) return;
  const int cw = std::max(1, static_cast<int>(std::lround(c.centre_px / c.bin_px)));
  const int gw = static_cast<int>(std::lround(c.side_gap_px / c.bin_px));
  const int sw = std::max(1, static_cast<int>(std::lround(c.side_px / c.bin_px)));
  const int steps = static_cast<int>(std::floor(c.direction_range_rad / c.direction_step_rad));
  const int n_seg = c.segments;
  const double min_n = c.min_window_samples;
  const uint8_t bit = static_cast<uint8_t>(1u << axis);
  for (int step = -steps; step <= steps; ++step) {
    const double phi = phi_c + step * c.direction_step_rad;
    const float sn = static_cast<float>(std::sin(phi)), cs = static_cast<float>(std::cos(phi));
    float v_lo = 1e30f, v_hi = -1e30f, u_lo = 1e30f, u_hi = -1e30f;
    for (int k = 0; k < n_hull; ++k) {
      const Eigen::Vector2f& h = hull_[static_cast<size_t>(k)];
      v_lo = std::min(v_lo, -sn * h.x() + cs * h.y());
      v_hi = std::max(v_hi, -sn * h.x() + cs * h.y());
      u_lo = std::min(u_lo, cs * h.x() + sn * h.y());
      u_hi = std::max(u_hi, cs * h.x() + sn * h.y());
    }
    const double span = v_hi - v_lo;
    if (!(span > 2.0 * c.min_plate_width_m) || !(u_hi > u_lo)) continue;
    const double bin = std::max(c.bin_px / px_per_m, span / (c.max_bins - 1));
    const int nb = static_cast<int>(span / bin) + 1;
    const size_t row = static_cast<size_t>(nb + 1);  // one part's prefix sums
    const size_t used = row * static_cast<size_t>(n_seg);
    std::fill(n_.begin(), n_.begin() + used, 0.0);
    std::fill(dark_.begin(), dark_.begin() + used, 0.0);
    std::fill(depth_sum_.begin(), depth_sum_.begin() + used, 0.0);
    std::fill(depth_n_.begin(), depth_n_.begin() + used, 0.0);
    const float inv_bin = static_cast<float>(1.0 / bin);
    const float inv_seg = static_cast<float>(n_seg / (u_hi - u_lo));
    for (int i = 0; i < n_samples; ++i) {
      const Sample& s = samples_[static_cast<size_t>(i)];
      const int k = static_cast<int>((-sn * s.a1 + cs * s.a2 - v_lo) * inv_bin);
      if (k < 0 || k >= nb) continue;
      const int seg = std::clamp(static_cast<int>((cs * s.a1 + sn * s.a2 - u_lo) * inv_seg), 0, n_seg - 1);
      const size_t j = static_cast<size_t>(seg) * row + static_cast<size_t>(k + 1);
      n_[j] += 1.0;
      dark_[j] += (s.dark & bit) ? 1.0 : 0.0;
      if (!std::isnan(s.residual)) {
        depth_sum_[j] += s.residual;
        depth_n_[j] += 1.0;
      }
    }
    for (int seg = 0; seg < n_seg; ++seg) {  // prefix sums: window [a, b) sums to P[b] - P[a]
      const size_t o = static_cast<size_t>(seg) * row;
      for (size_t k = 1; k < row; ++k) {
        n_[o + k] += n_[o + k - 1];
        dark_[o + k] += dark_[o + k - 1];
        depth_sum_[o + k] += depth_sum_[o + k - 1];
        depth_n_[o + k] += depth_n_[o + k - 1];
      }
    }
    auto window = [row](const std::vector<double>& p, int seg, int a, int b) {
      const size_t o = static_cast<size_t>(seg) * row;
      return p[o + static_cast<size_t>(b)] - p[o + static_cast<size_t>(a)];
    };
    // Line window [k, k + cw); sides [k - gw - sw, k - gw) and [k + cw + gw, k + cw + gw + sw).
    const int k_first = gw + sw, k_last = nb - cw - gw - sw;
    // Per part: the rate of dark pixels and the overdispersion of the line windows' dark counts.
    double p0[kMaxSegments], phi_over[kMaxSegments];
    for (int seg = 0; seg < n_seg && use_dark; ++seg) {
      const double n_all = window(n_, seg, 0, nb);
      p0[seg] = n_all > 0 ? std::clamp(window(dark_, seg, 0, nb) / n_all, 0.01, 0.99) : 0.5;
      const double var = p0[seg] * (1.0 - p0[seg]);
      int n_windows = 0;
      for (int k = k_first; k <= k_last; ++k) {
        const double n = window(n_, seg, k, k + cw);
        if (n < min_n) continue;
        const double e = window(dark_, seg, k, k + cw) - n * p0[seg];
        scratch_[static_cast<size_t>(n_windows++)] = e * e / (n * var);
      }
      phi_over[seg] = n_windows >= 8 ? std::max(1.0, median(scratch_.data(), n_windows) / 0.455) : kInf;
    }
    auto z_at = [&](int k) {
      if (k < k_first || k > k_last) return -kInf;
      PartSum dark, depth;
      for (int seg = 0; seg < n_seg; ++seg) {
        const double nc = window(n_, seg, k, k + cw);
        if (use_dark && std::isfinite(phi_over[seg]) && nc >= min_n) {
          const double var = p0[seg] * (1.0 - p0[seg]);
          dark.add((window(dark_, seg, k, k + cw) - nc * p0[seg]) / std::sqrt(phi_over[seg] * nc * var),
                   c.min_segment_z);
        }
        const double dc = window(depth_n_, seg, k, k + cw), dl = window(depth_n_, seg, k - gw - sw, k - gw),
                     dr = window(depth_n_, seg, k + cw + gw, k + cw + gw + sw);
        if (dc < min_n || dl < min_n || dr < min_n) continue;
        const double dip = window(depth_sum_, seg, k, k + cw) / dc -
                           0.5 * (window(depth_sum_, seg, k - gw - sw, k - gw) / dl +
                                  window(depth_sum_, seg, k + cw + gw, k + cw + gw + sw) / dr);
        depth.add(dip / (sigma_z_m * std::sqrt(1.0 / dc + 0.25 / dl + 0.25 / dr)), c.min_segment_z);
      }
      // The cues' noises are independent (the texture and the pixel noise; the stereo noise): where
      // both are measured, their Stouffer sum counts too (a gap a little dark and a little deep).
      const double z_dark = dark.z(), z_depth = depth.z();
      const double z_both =
          std::isfinite(z_dark) && std::isfinite(z_depth) ? (z_dark + z_depth) / std::sqrt(2.0) : -kInf;
      return std::max(std::max(z_dark, z_depth), z_both);
    };
    // Offsets at least min_plate_width_m inside the region on both sides.
    const int k_lo = std::max(k_first, static_cast<int>(std::ceil(c.min_plate_width_m / bin - 0.5 * cw)));
    const int k_hi =
        std::min(k_last, static_cast<int>(std::floor((span - c.min_plate_width_m) / bin - 0.5 * cw)));
    for (int k = k_lo; k <= k_hi; ++k) {
      const double z = z_at(k);
      if (!(z > best->z) || z < c.support_z) continue;
      // Sub-bin offset: the vertex of the parabola through the significance at k - 1, k, k + 1.
      const double zm = z_at(k - 1), zp = z_at(k + 1), curvature = zm - 2.0 * z + zp;
      const double delta = std::isfinite(zm) && std::isfinite(zp) && curvature < 0.0
                               ? std::clamp(0.5 * (zm - zp) / curvature, -0.5, 0.5)
                               : 0.0;
      best->found = true;
      best->phi = phi;
      best->rho = v_lo + (k + 0.5 * cw + delta) * bin;
      best->z = z;
    }
  }
}

// The seam's ends along it (header): per side of the seam, bins along it of the heights above the
// support in the band beside it; the step down at each end is where the running sum of (height -
// thickness / 2) from the middle outwards peaks (the least-squares step with the two levels known),
// moved into the outer bin by its mean's share of the thickness. The inner ends of the two sides.
bool ButtFinder::seam_ends(const OrganizedCloud& cloud, const cv::Mat& depth_m, const RaisedRegion& region,
                           const Plane2d& plane, const Line& line, int n_hull, double* t0, double* t1,
                           std::array<bool, 2>* seen_beyond) {
  const ButtConfig& c = config_;
  const double sn = std::sin(line.phi), cs = std::cos(line.phi);
  const Eigen::Vector3d along = cs * plane.e1 + sn * plane.e2;
  double u_lo = 1e30, u_hi = -1e30;
  for (int k = 0; k < n_hull; ++k) {
    const double u = cs * hull_[static_cast<size_t>(k)].x() + sn * hull_[static_cast<size_t>(k)].y();
    u_lo = std::min(u_lo, u);
    u_hi = std::max(u_hi, u);
  }
  // Bins one pixel long along the seam (at the plane's origin); the depth image's pixels (not the
  // grid's: a finer step, four times the points).
  const double px_per_m = image_direction(plane, along).norm();
  if (!(px_per_m > 0)) return false;
  const double start = u_lo - c.end_search_m;
  const double span = (u_hi - u_lo) + 2.0 * c.end_search_m;
  const double bin = std::max(1.0 / px_per_m, span / (c.max_bins - 1));
  const int nb = static_cast<int>(span / bin) + 1;
  std::fill(end_sum_.begin(), end_sum_.begin() + 2 * nb, 0.0);
  std::fill(end_n_.begin(), end_n_.begin() + 2 * nb, 0.0);
  // The region's box and a margin: the step down lies within end_search_m of the region.
  const int s = cloud.stride_px(), margin = 60;
  const int u0 = std::max(0, region.min_x * s - margin),
            u1 = std::min(K_.width - 1, region.max_x * s + margin);
  const int v0 = std::max(0, region.min_y * s - margin),
            v1 = std::min(K_.height - 1, region.max_y * s + margin);
  const double max_height = 3.0 * region.thickness_m, half = 0.5 * region.thickness_m;
  const float min_depth = cloud.min_depth_m(), max_depth = cloud.max_depth_m();
  for (int v = v0; v <= v1; ++v) {
    const float* depth_row = depth_m.ptr<float>(v);
    for (int u = u0; u <= u1; ++u) {
      const float z = depth_row[u];
      if (!std::isfinite(z) || !(z >= min_depth && z <= max_depth)) continue;
      // The pixel's place is where its ray crosses the top plane (exact; the measured point's noise
      // along the ray would smear the step); its height is the measured point's.
      const Eigen::Vector3d ray((u - K_.cx) / K_.fx, (v - K_.cy) / K_.fy, 1.0);
      const double h = region.support.signed_distance(z * ray);
      if (std::fabs(h) > max_height) continue;
      const double den = plane.normal.dot(ray);
      if (std::fabs(den) < 1e-9) continue;
      const Eigen::Vector3d q = plane.normal.dot(plane.origin) / den * ray - plane.origin;
      const double a1 = plane.e1.dot(q), a2 = plane.e2.dot(q);
      const double across = -sn * a1 + cs * a2 - line.rho;
      if (std::fabs(across) < c.end_band_near_m || std::fabs(across) > c.end_band_far_m) continue;
      const int k = static_cast<int>((cs * a1 + sn * a2 - start) / bin);
      if (k < 0 || k >= nb) continue;
      const size_t i = static_cast<size_t>((across > 0 ? nb : 0) + k);
      end_sum_[i] += h;
      end_n_[i] += 1.0;
    }
  }
  const int mid = static_cast<int>((0.5 * (u_lo + u_hi) - start) / bin);
  const int search = static_cast<int>(std::ceil(c.end_search_m / bin));
  double lo_end[2], hi_end[2];
  bool lo_seen[2], hi_seen[2];
  for (int side = 0; side < 2; ++side) {
    const double* sum = end_sum_.data() + side * nb;
    const double* n = end_n_.data() + side * nb;
    auto mean_fraction = [&](int k) {  // the bin's share of the thickness, 0 when empty
      return n[k] > 0 ? std::clamp(sum[k] / n[k] / region.thickness_m, 0.0, 1.0) : 0.0;
    };
    auto support_seen = [&](int from, int to) {  // a bin of the support within [from, to]
      for (int k = std::max(0, from); k <= std::min(nb - 1, to); ++k)
        if (n[k] >= 2 && sum[k] / n[k] < half) return true;
      return false;
    };
    // Low end: scanning down from the middle, the strict maximum keeps the innermost of equal sums
    // (empty bins: the support hidden behind the plate's far end).
    double run = 0.0, best = 0.0;
    int best_k = -1;
    for (int k = mid; k >= 0; --k) {
      run += sum[k] - half * n[k];
      if (run > best) {
        best = run;
        best_k = k;
      }
    }
    if (best_k < 0) return false;
    lo_end[side] = start + (best_k - (best_k > 0 ? mean_fraction(best_k - 1) : 0.0)) * bin;
    lo_seen[side] = support_seen(best_k - search, best_k - 1);
    run = 0.0;
    best = 0.0;
    best_k = -1;
    for (int k = mid; k < nb; ++k) {
      run += sum[k] - half * n[k];
      if (run > best) {
        best = run;
        best_k = k;
      }
    }
    if (best_k < 0) return false;
    hi_end[side] = start + (best_k + 1 + (best_k + 1 < nb ? mean_fraction(best_k + 1) : 0.0)) * bin;
    hi_seen[side] = support_seen(best_k + 1, best_k + search);
  }
  const int lo_side = lo_end[0] >= lo_end[1] ? 0 : 1, hi_side = hi_end[0] <= hi_end[1] ? 0 : 1;
  *t0 = lo_end[lo_side];
  *t1 = hi_end[hi_side];
  // An end whose face the camera sees (the ray to it runs inwards along the seam): the face's pixels,
  // heights thickness..0 below the top edge, cross the top plane up to thickness |r . u| / |r . n|
  // beyond the end, and the step at half the thickness lies half of that beyond it.
  for (int e = 0; e < 2; ++e) {
    double& t = e == 0 ? *t0 : *t1;
    const Eigen::Vector3d ray =
        (plane.origin + line.rho * (-sn * plane.e1 + cs * plane.e2) + t * along).normalized();
    const double outward = (e == 0 ? -1.0 : 1.0) * ray.dot(along), down = std::fabs(ray.dot(plane.normal));
    if (outward < 0.0 && down > 0.05) t -= (e == 0 ? -1.0 : 1.0) * 0.5 * region.thickness_m * -outward / down;
  }
  (*seen_beyond)[0] = lo_seen[lo_side];
  (*seen_beyond)[1] = hi_seen[hi_side];
  return *t1 > *t0;
}

int ButtFinder::find(const OrganizedCloud& cloud, const RaisedRegionFinder& raised, const cv::Mat* bgr,
                     const cv::Mat& depth_m, DetectionList* out) {
  const ButtConfig& c = config_;
  if (depth_m.type() != CV_32FC1 || depth_m.cols != K_.width || depth_m.rows != K_.height) return 0;
  if (bgr != nullptr && (bgr->type() != CV_8UC3 || bgr->cols != K_.width || bgr->rows != K_.height)) return 0;
  if (cloud.width() * cloud.stride_px() < K_.width || cloud.height() * cloud.stride_px() < K_.height)
    return 0;
  int appended = 0;
  for (int r = 0; r < raised.region_count(); ++r) {
    const RaisedRegion& region = raised.region(r);
    Plane2d plane;
    plane.normal = region.top.normal;
    plane.origin = region.top.centroid;
    plane.e1 = Eigen::Vector3d::UnitX() - plane.normal.x() * plane.normal;
    if (plane.e1.norm() < 1e-3) plane.e1 = Eigen::Vector3d::UnitY() - plane.normal.y() * plane.normal;
    plane.e1.normalize();
    plane.e2 = plane.normal.cross(plane.e1);
    const int n_hull = hull(collect_border(cloud, raised, r, plane));
    double phi[2];
    if (n_hull < 3 || !rectangle_axes(n_hull, phi)) continue;
    const int n_samples = collect_samples(cloud, raised, r, plane, phi, bgr, depth_m);
    Line line;
    const double sigma_z = noise_.sigma_m(plane.origin.z());
    for (int axis = 0; axis < 2; ++axis)
      sweep_direction(plane, n_samples, n_hull, phi[axis], axis, bgr != nullptr, sigma_z, &line);
    double t0, t1;
    std::array<bool, 2> seen_beyond{false, false};
    if (!line.found || !seam_ends(cloud, depth_m, region, plane, line, n_hull, &t0, &t1, &seen_beyond))
      continue;
    const double length = t1 - t0;
    if (length < c.min_length_m || length > c.max_length_m) continue;

    const double sn = std::sin(line.phi), cs = std::cos(line.phi);
    Eigen::Vector3d along = cs * plane.e1 + sn * plane.e2;
    const Eigen::Vector3d across = -sn * plane.e1 + cs * plane.e2;
    const Eigen::Vector3d on_line = plane.origin + line.rho * across;
    Detection det;
    det.source = DetectionSource::kGeometry;
    det.kind = SeamKind::kButt;
    det.support_only = line.z < c.min_z;
    det.seam_cam[0] = on_line + t0 * along;
    det.seam_cam[1] = on_line + t1 * along;
    // A fixed orientation (left to right in the image), as the fillets'.
    if (along.x() < 0) {
      std::swap(det.seam_cam[0], det.seam_cam[1]);
      std::swap(seen_beyond[0], seen_beyond[1]);
      along = -along;
    }
    for (int e = 0; e < 2; ++e) {
      Eigen::Vector2d px;
      det.end_observed[e] =
          seen_beyond[e] && project(K_, det.seam_cam[e], &px) && inside_image(K_, px, c.end_margin_px);
    }
    det.plate_normal_cam = {plane.normal, plane.normal};
    // Box: x along the seam, z the plates' normal; across the region's extent, down to the support.
    double v_lo = kInf, v_hi = -kInf;
    for (int k = 0; k < n_hull; ++k) {
      const double v = -sn * hull_[static_cast<size_t>(k)].x() + cs * hull_[static_cast<size_t>(k)].y();
      v_lo = std::min(v_lo, v);
      v_hi = std::max(v_hi, v);
    }
    Eigen::Matrix3d R;
    R.col(0) = along;
    R.col(2) = plane.normal;
    R.col(1) = R.col(2).cross(R.col(0));
    det.T_cam_box.linear() = R;
    det.T_cam_box.translation() = 0.5 * (det.seam_cam[0] + det.seam_cam[1]) +
                                  (0.5 * (v_lo + v_hi) - line.rho) * across -
                                  0.5 * region.thickness_m * plane.normal;
    det.half_size_m = Eigen::Vector3d(0.5 * length, 0.5 * (v_hi - v_lo), 0.5 * region.thickness_m) +
                      Eigen::Vector3d::Constant(c.box_margin_m);
    det.box_px = box_image_rect(K_, det.T_cam_box, det.half_size_m);
    det.confidence =
        static_cast<float>(std::min(1.0, line.z / (2.0 * c.min_z)) * std::min(1.0, length / 0.3));
    if (!out->push(det)) return appended;
    ++appended;
  }
  return appended;
}

}  // namespace hwr::detect
