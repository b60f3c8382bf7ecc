#include "hwr/detect/raised_regions.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include <Eigen/Geometry>

namespace hwr::detect {
namespace {

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
constexpr int kMaxPlanes = 64;
constexpr int kMinRegionPoints = 30;  // grid points: a region's plane is fitted from them  // the planes
                                      // looked at (PlaneSegmentationConfig::max_planes' default)

double angle_rad(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::atan2(a.cross(b).norm(), std::fabs(a.dot(b)));
}

}  // namespace

RaisedRegionFinder::RaisedRegionFinder(const RaisedRegionConfig& config, const DepthNoiseModel& noise,
                                       int grid_width, int grid_height)
    : config_(config), noise_(noise), grid_width_(grid_width), grid_height_(grid_height) {
  const size_t n = static_cast<size_t>(grid_width) * static_cast<size_t>(grid_height);
  height_.assign(n, kNaN);
  mean_height_.assign(n, kNaN);
  raised_.assign(n, 0);
  sum_.assign(static_cast<size_t>(grid_width + 1) * static_cast<size_t>(grid_height + 1), 0.0);
  count_.assign(sum_.size(), 0.0);
  label_.assign(n, -1);
  inner_.assign(n, 0);
  queue_.assign(n, 0);
  regions_.reserve(static_cast<size_t>(config.max_regions));
}

core::Expected<RaisedRegionFinder> RaisedRegionFinder::create(const RaisedRegionConfig& c,
                                                              const DepthNoiseModel& noise, int grid_width,
                                                              int grid_height) {
  if (!(c.max_support_tilt_rad > 0) || !(c.layer_max_angle_rad > 0) || !(c.layer_max_offset_m > 0) ||
      c.max_layers < 1) {
    return core::InvalidArgument(
        "raised regions: max_support_tilt_rad, layer_max_angle_rad, layer_max_offset_m must be positive, "
        "max_layers >= 1");
  }
  if (c.window_points < 1 || c.window_points % 2 == 0) {
    return core::InvalidArgument("raised regions: window_points must be odd and >= 1, got " +
                                 std::to_string(c.window_points));
  }
  if (!(c.min_thickness_m > 0) || !(c.max_thickness_m > c.min_thickness_m) ||
      !(c.max_abs_height_m > c.max_thickness_m)) {
    return core::InvalidArgument(
        "raised regions: need 0 < min_thickness_m < max_thickness_m < max_abs_height_m");
  }
  if (!(c.max_mean_sigma_fraction > 0) || !(c.min_area_m2 > 0) || !(c.max_top_tilt_rad > 0) ||
      !(c.min_support_fraction >= 0 && c.min_support_fraction <= 1) || c.max_regions < 1) {
    return core::InvalidArgument(
        "raised regions: max_mean_sigma_fraction, min_area_m2, max_top_tilt_rad must be positive, "
        "min_support_fraction in [0, 1], max_regions >= 1");
  }
  if (grid_width < c.window_points || grid_height < c.window_points) {
    return core::InvalidArgument("raised regions: a grid of " + std::to_string(grid_width) + "x" +
                                 std::to_string(grid_height) + " points is smaller than the window");
  }
  return RaisedRegionFinder(c, noise, grid_width, grid_height);
}

int RaisedRegionFinder::find(const OrganizedCloud& cloud, const PlaneSegmenter& planes,
                             const Eigen::Vector3d& up_cam) {
  regions_.clear();
  if (regions_.capacity() < static_cast<size_t>(config_.max_regions))
    regions_.reserve(static_cast<size_t>(config_.max_regions));  // a copy does not keep the capacity
  if (cloud.width() != grid_width_ || cloud.height() != grid_height_) return 0;
  std::fill(label_.begin(), label_.end(), -1);
  const int n_planes = planes.plane_count();
  const double cos_tilt = std::cos(config_.max_support_tilt_rad);
  // Layers: the largest unassigned horizontal plane and the planes parallel to it within
  // layer_max_offset_m (planes are sorted largest first). assigned[]: -1 not horizontal, -2 horizontal
  // and unassigned, else the layer.
  int members[kMaxPlanes];
  int assigned[kMaxPlanes];
  const int n = std::min(n_planes, kMaxPlanes);
  for (int i = 0; i < n; ++i) {
    const PlaneFit& f = planes.plane(i).fit;
    assigned[i] = f.ok && f.normal.dot(up_cam) >= cos_tilt ? -2 : -1;
  }
  int layers = 0;
  for (int seed = 0; seed < n && layers < config_.max_layers; ++seed) {
    // A support holds a pair of plates and a border around them (the planes are sorted largest first).
    if (planes.plane(seed).cells < config_.min_layer_cells) break;
    if (assigned[seed] != -2) continue;
    const PlaneFit& s = planes.plane(seed).fit;
    int n_members = 0, support = seed;
    double lowest = 0.0;
    for (int j = seed; j < n; ++j) {
      if (assigned[j] != -2) continue;
      const PlaneFit& f = planes.plane(j).fit;
      const double offset = s.signed_distance(f.centroid);
      if (angle_rad(s.normal, f.normal) > config_.layer_max_angle_rad ||
          std::fabs(offset) > config_.layer_max_offset_m)
        continue;
      assigned[j] = layers;
      members[n_members++] = j;
      // The support is the lowest member (normals face the camera, above the surface).
      if (offset < lowest && planes.plane(j).cells * 8 >= planes.plane(seed).cells) {
        lowest = offset;
        support = j;
      }
    }
    find_in_layer(cloud, planes, members, n_members, support);
    ++layers;
  }
  return region_count();
}

void RaisedRegionFinder::heights(const OrganizedCloud& cloud, const PlaneSegmenter& planes,
                                 const bool* in_layer, const PlaneFit& support, const Box& box) {
  const Eigen::Vector3f n = support.normal.cast<float>();
  const float d = static_cast<float>(support.d), max_abs = static_cast<float>(config_.max_abs_height_m);
  for (int y = box.y0; y <= box.y1; ++y) {
    for (int x = box.x0; x <= box.x1; ++x) {
      float& h = height_[static_cast<size_t>(y) * grid_width_ + x];
      h = kNaN;
      const int l = planes.point_label(cloud, x, y);
      if (l < 0 || l >= kMaxPlanes || !in_layer[l]) continue;
      const float dist = n.dot(cloud.point(x, y)) - d;
      if (std::fabs(dist) <= max_abs) h = dist;
    }
  }
}

// Box means of the heights over window_points^2 (clipped to the box) from integral images; NaN where
// the point has no height or the window holds fewer than half its points.
void RaisedRegionFinder::box_means(const Box& box) {
  const int bw = box.x1 - box.x0 + 1, bh = box.y1 - box.y0 + 1;
  const int stride = bw + 1;
  for (int i = 0; i <= bw; ++i) sum_[static_cast<size_t>(i)] = count_[static_cast<size_t>(i)] = 0.0;
  for (int y = 0; y < bh; ++y) {
    double row_sum = 0.0, row_count = 0.0;
    const size_t above = static_cast<size_t>(y) * stride, here = above + stride;
    sum_[here] = count_[here] = 0.0;
    for (int x = 0; x < bw; ++x) {
      const float h = height_[static_cast<size_t>(y + box.y0) * grid_width_ + (x + box.x0)];
      if (!std::isnan(h)) {
        row_sum += h;
        row_count += 1.0;
      }
      sum_[here + x + 1] = sum_[above + x + 1] + row_sum;
      count_[here + x + 1] = count_[above + x + 1] + row_count;
    }
  }
  const int r = config_.window_points / 2;
  const double min_count = 0.5 * config_.window_points * config_.window_points;
  for (int y = 0; y < bh; ++y) {
    const int ya = std::max(0, y - r), yb = std::min(bh, y + r + 1);
    for (int x = 0; x < bw; ++x) {
      const size_t g = static_cast<size_t>(y + box.y0) * grid_width_ + (x + box.x0);
      mean_height_[g] = kNaN;
      if (std::isnan(height_[g])) continue;
      const int xa = std::max(0, x - r), xb = std::min(bw, x + r + 1);
      const size_t a = static_cast<size_t>(ya) * stride, b = static_cast<size_t>(yb) * stride;
      const double c = count_[b + xb] - count_[a + xb] - count_[b + xa] + count_[a + xa];
      if (c < min_count) continue;
      mean_height_[g] = static_cast<float>((sum_[b + xb] - sum_[a + xb] - sum_[b + xa] + sum_[a + xa]) / c);
    }
  }
}

void RaisedRegionFinder::find_in_layer(const OrganizedCloud& cloud, const PlaneSegmenter& planes,
                                       const int* members, int n_members, int support_plane) {
  const RaisedRegionConfig& c = config_;
  bool in_layer[kMaxPlanes] = {};
  for (int k = 0; k < n_members; ++k) in_layer[members[k]] = true;
  // The layer's grid box: its planes' cells, one cell wider (their border points).
  const int cp = planes.cell_points();
  Box box{grid_width_, grid_height_, -1, -1};
  for (int k = 0; k < n_members; ++k) {
    const PlaneRegion& r = planes.plane(members[k]);
    box.x0 = std::min(box.x0, (r.min_cx - 1) * cp);
    box.y0 = std::min(box.y0, (r.min_cy - 1) * cp);
    box.x1 = std::max(box.x1, (r.max_cx + 2) * cp - 1);
    box.y1 = std::max(box.y1, (r.max_cy + 2) * cp - 1);
  }
  box.x0 = std::max(box.x0, 0);
  box.y0 = std::max(box.y0, 0);
  box.x1 = std::min(box.x1, grid_width_ - 1);
  box.y1 = std::min(box.y1, grid_height_ - 1);
  if (box.x1 < box.x0 || box.y1 < box.y0) return;

  const double tau = 0.5 * c.min_thickness_m;
  const double max_mean_sigma = c.max_mean_sigma_fraction * c.min_thickness_m;
  const double window_points = static_cast<double>(c.window_points) * c.window_points;
  const double inv_f = 1.0 / cloud.intrinsics().fx;
  PlaneFit support = planes.plane(support_plane).fit;
  // The support's own fit holds the plates where the segmentation merged them (a tenth of its points
  // 1 cm higher lifts it 1 mm): refitted from the points whose mean is below tau (every other row and
  // column: a surface's fit needs no more), unless too few points are above tau to make a region.
  // Raised: the mean at least tau above the support (and not above a plate), resolved by the noise.
  auto is_raised = [&](int x, int y) -> unsigned char {
    const float h = mean_height_[static_cast<size_t>(y) * grid_width_ + x];
    if (std::isnan(h) || h < tau || h > c.max_thickness_m + tau) return 0;
    const Eigen::Vector3d p = cloud.point(x, y).cast<double>();
    const double sigma_mean =
        noise_.sigma_m(p.z()) * std::fabs(support.normal.dot(p.normalized())) / std::sqrt(window_points);
    return sigma_mean <= max_mean_sigma ? 1 : 0;
  };
  heights(cloud, planes, in_layer, support, box);
  box_means(box);
  int above = 0;
  PlaneMoments low;
  for (int y = box.y0; y <= box.y1; ++y) {
    for (int x = box.x0; x <= box.x1; ++x) {
      const float h = mean_height_[static_cast<size_t>(y) * grid_width_ + x];
      if (std::isnan(h)) continue;
      if (h >= tau) {
        above += is_raised(x, y);
      } else if (((x | y) & 1) == 0) {
        low.add(cloud.point(x, y).cast<double>());
      }
    }
  }
  if (above < kMinRegionPoints) return;
  const PlaneFit refit = low.n >= 30 ? fit_plane(low) : PlaneFit{};
  if (refit.ok && angle_rad(refit.normal, support.normal) <= c.layer_max_angle_rad) {
    support = refit;
    heights(cloud, planes, in_layer, support, box);
    box_means(box);
  }

  // Raised points.
  for (int y = box.y0; y <= box.y1; ++y) {
    for (int x = box.x0; x <= box.x1; ++x)
      raised_[static_cast<size_t>(y) * grid_width_ + x] = is_raised(x, y);
  }

  // Regions: 4-connected raised points (breadth first), each tested as a plate (or plates) on the
  // support.
  for (int y0 = box.y0; y0 <= box.y1; ++y0) {
    for (int x0 = box.x0; x0 <= box.x1; ++x0) {
      const size_t g0 = static_cast<size_t>(y0) * grid_width_ + x0;
      if (!raised_[g0] || label_[g0] != -1) continue;
      if (static_cast<int>(regions_.size()) >= c.max_regions) break;
      const int id = static_cast<int>(regions_.size());
      int head = 0, tail = 0;
      queue_[static_cast<size_t>(tail++)] = static_cast<int>(g0);
      label_[g0] = id;
      RaisedRegion r;
      r.min_x = r.max_x = x0;
      r.min_y = r.max_y = y0;
      PlaneMoments m;
      double mean_height = 0.0;
      int outside = 0, supported = 0;
      while (head < tail) {
        const int g = queue_[static_cast<size_t>(head++)];
        const int x = g % grid_width_, y = g / grid_width_;
        const Eigen::Vector3d p = cloud.point(x, y).cast<double>();
        m.add(p);
        mean_height += mean_height_[static_cast<size_t>(g)];
        // A grid point's patch on the support: (stride z / f)^2, stretched by 1 / |n . r|.
        const double side = cloud.stride_px() * p.z() * inv_f;
        r.area_m2 += side * side / std::max(0.05, std::fabs(support.normal.dot(p.normalized())));
        r.min_x = std::min(r.min_x, x);
        r.max_x = std::max(r.max_x, x);
        r.min_y = std::min(r.min_y, y);
        r.max_y = std::max(r.max_y, y);
        const int nb[4] = {x > box.x0 ? g - 1 : -1, x < box.x1 ? g + 1 : -1,
                           y > box.y0 ? g - grid_width_ : -1, y < box.y1 ? g + grid_width_ : -1};
        for (const int q : nb) {
          if (q >= 0 && !raised_[static_cast<size_t>(q)]) {
            // A neighbour outside the region: the support (a mean below tau), or something else (another
            // surface, no depth, the layer's edge).
            const float hq = mean_height_[static_cast<size_t>(q)];
            ++outside;
            supported += !std::isnan(hq) && hq < tau ? 1 : 0;
          }
          if (q < 0 || !raised_[static_cast<size_t>(q)] || label_[static_cast<size_t>(q)] != -1) continue;
          label_[static_cast<size_t>(q)] = id;
          queue_[static_cast<size_t>(tail++)] = q;
        }
      }
      r.points = tail;
      mean_height /= tail;
      // The region's plane from its inner points: the box mean blurs a plate's border with its
      // support over half a window, and those points would lower and tilt it.
      PlaneMoments inner;
      for (int k = 0; k < tail; ++k) {
        const int g = queue_[static_cast<size_t>(k)];
        inner_[static_cast<size_t>(g)] = mean_height_[static_cast<size_t>(g)] >= 0.75 * mean_height ? 1 : 0;
        if (inner_[static_cast<size_t>(g)])
          inner.add(cloud.point(g % grid_width_, g / grid_width_).cast<double>());
      }
      r.support = support;
      r.top = fit_plane(inner.n >= 30 ? inner : m);
      r.support_fraction = outside > 0 ? static_cast<double>(supported) / outside : 0.0;
      bool keep = r.points >= kMinRegionPoints && r.area_m2 >= c.min_area_m2 &&
                  r.support_fraction >= c.min_support_fraction && r.top.ok &&
                  angle_rad(r.top.normal, support.normal) <= c.max_top_tilt_rad;
      if (keep) {
        r.thickness_m = support.signed_distance(r.top.centroid);
        keep = r.thickness_m >= c.min_thickness_m && r.thickness_m <= c.max_thickness_m;
      }
      if (keep) {
        regions_.push_back(r);
      } else {
        // Not a plate: its points are left unlabelled but visited (-2), then cleared.
        for (int k = 0; k < tail; ++k) label_[static_cast<size_t>(queue_[static_cast<size_t>(k)])] = -2;
      }
    }
  }
  for (int y = box.y0; y <= box.y1; ++y) {
    for (int x = box.x0; x <= box.x1; ++x) {
      int& l = label_[static_cast<size_t>(y) * grid_width_ + x];
      if (l == -2) l = -1;
    }
  }
}

}  // namespace hwr::detect
