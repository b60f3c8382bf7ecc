#include "hwr/detect/plane_segmentation.hpp"

#include <algorithm>
#include <cmath>
#include <string>

#include <Eigen/Geometry>

namespace hwr::detect {
namespace {

constexpr double kPi = 3.14159265358979323846;

bool finite_at_least(double v, double lo) { return std::isfinite(v) && v >= lo; }

// Sum of squared distances of the moments' points to their own plane.
double sse(const PlaneMoments& m, const PlaneFit& f) { return m.n * f.rms_m * f.rms_m; }

// Standard error (radians, per axis) of the normal of a plane fitted to the moments' points with
// noise sigma_across along the normal: sigma / sqrt(n lambda), lambda the smaller in-plane
// eigenvalue of their scatter (the plane's weaker direction).
double normal_sigma_rad(const PlaneMoments& m, const PlaneFit& f, double sigma_across) {
  const Eigen::Matrix3d scatter = m.sum_outer / m.n - f.centroid * f.centroid.transpose();
  const Eigen::Vector3d u = f.normal.unitOrthogonal(), v = f.normal.cross(u);
  const double a = u.dot(scatter * u), b = u.dot(scatter * v), c = v.dot(scatter * v);
  const double lambda = 0.5 * (a + c) - std::sqrt(0.25 * (a - c) * (a - c) + b * b);
  return lambda > 0.0 ? sigma_across / std::sqrt(m.n * lambda) : kPi;
}

// The depth noise across a plane at point p: sigma(z) along the viewing ray, times |n . r|.
double sigma_across(const DepthNoiseModel& noise, const Eigen::Vector3d& normal, const Eigen::Vector3d& p) {
  return noise.sigma_m(p.z()) * std::abs(normal.dot(p.normalized()));
}

// Whether two sets of points (moments and their own fits: cells or regions) lie on one plane; if so
// *joined is the plane of their union. All three tests must pass:
// (a) the normals within merge_angle_rad, or within merge_offset_sigmas standard errors of their
//     difference where the noise cannot resolve merge_angle_rad (a 36-point cell at 3 m: ~7 deg
//     per axis); (c) then decides.
// (b) the centroid of the one with fewer points within merge_offset_sigmas sigma(z) +
//     merge_offset_floor_m of the other's plane (the better one: a cell's plane extrapolated to a
//     region's centroid a metre away is off by its normal's error times a metre).
// (c) one plane for both costs no more squared distance than the noise explains: SSE(A u B) -
//     SSE(A) - SSE(B) is sigma^2 chi-square with 3 degrees of freedom when both lie on one plane
//     (an F-test with the noise known), tested at merge_offset_sigmas^2 * 3 with the larger sigma
//     across the joined plane at the two centroids, plus the cell RMS floor. This keeps out a cell
//     across a concave corner, which passes (a), (b) and the planarity test by the noise bound but
//     would bias the plane.
bool same_plane(const PlaneMoments& ma, const PlaneFit& fa, const PlaneMoments& mb, const PlaneFit& fb,
                const PlaneSegmentationConfig& config, const DepthNoiseModel& noise, PlaneFit* joined_fit,
                PlaneMoments* joined) {
  const double k = config.merge_offset_sigmas;
  const double sa = sigma_across(noise, fa.normal, fa.centroid),
               sb = sigma_across(noise, fb.normal, fb.centroid);
  const double angle = std::atan2(fa.normal.cross(fb.normal).norm(), fa.normal.dot(fb.normal));
  if (angle > config.merge_angle_rad) {
    const double na = normal_sigma_rad(ma, fa, sa), nb = normal_sigma_rad(mb, fb, sb);
    if (angle > k * std::sqrt(na * na + nb * nb)) return false;
  }
  const PlaneFit& larger = ma.n >= mb.n ? fa : fb;
  const Eigen::Vector3d& c = ma.n >= mb.n ? fb.centroid : fa.centroid;
  if (std::abs(larger.signed_distance(c)) > k * noise.sigma_m(c.z()) + config.merge_offset_floor_m)
    return false;
  *joined = ma;
  joined->merge(mb);
  *joined_fit = fit_plane(*joined);
  if (!joined_fit->ok) return false;
  const double sigma = std::max(sigma_across(noise, joined_fit->normal, fa.centroid),
                                sigma_across(noise, joined_fit->normal, fb.centroid)) +
                       config.cell_rms_floor_m;
  return sse(*joined, *joined_fit) - sse(ma, fa) - sse(mb, fb) <= k * k * 3.0 * sigma * sigma;
}

void include_cell(int cx, int cy, PlaneRegion* r) {
  r->min_cx = std::min(r->min_cx, cx);
  r->max_cx = std::max(r->max_cx, cx);
  r->min_cy = std::min(r->min_cy, cy);
  r->max_cy = std::max(r->max_cy, cy);
}

}  // namespace

PlaneSegmenter::PlaneSegmenter(const PlaneSegmentationConfig& config, const DepthNoiseModel& noise,
                               int grid_width, int grid_height)
    : config_(config),
      noise_(noise),
      grid_width_(grid_width),
      grid_height_(grid_height),
      // Partial cells at the right and bottom border are not cells: their points can only join a
      // neighbouring plane as border points (point_label).
      cells_x_(grid_width / config.cell_points),
      cells_y_(grid_height / config.cell_points) {
  const size_t cells = static_cast<size_t>(cells_x_) * static_cast<size_t>(cells_y_);
  cell_moments_.resize(cells);
  cell_fit_.resize(cells);
  cell_planar_.assign(cells, 0);
  cell_order_.resize(cells);
  queue_.resize(cells);
  cell_label_.assign(cells, -1);
  point_label_.assign(static_cast<size_t>(grid_width) * static_cast<size_t>(grid_height), -1);
  plane_of_region_.assign(cells, -1);
  regions_.resize(cells);
  planes_.reserve(static_cast<size_t>(config.max_planes));
}

core::Expected<PlaneSegmenter> PlaneSegmenter::create(const PlaneSegmentationConfig& config,
                                                      const DepthNoiseModel& noise, int grid_width,
                                                      int grid_height) {
  const auto bad = [](const std::string& what) {
    return core::InvalidArgument("plane segmentation: " + what);
  };
  if (config.cell_points < 2) {
    return bad("cell_points must be >= 2 (a cell needs 3 points for a plane), got " +
               std::to_string(config.cell_points));
  }
  if (!(config.cell_min_valid > 0.0 && config.cell_min_valid <= 1.0)) {
    return bad("cell_min_valid must be in (0, 1], got " + std::to_string(config.cell_min_valid));
  }
  if (!finite_at_least(config.cell_max_rms_sigmas, 0.0)) {
    return bad("cell_max_rms_sigmas must be >= 0, got " + std::to_string(config.cell_max_rms_sigmas));
  }
  if (!finite_at_least(config.cell_rms_floor_m, 0.0)) {
    return bad("cell_rms_floor_m must be >= 0, got " + std::to_string(config.cell_rms_floor_m));
  }
  if (!(config.merge_angle_rad >= 0.0 && config.merge_angle_rad <= kPi)) {
    return bad("merge_angle_rad must be in [0, pi], got " + std::to_string(config.merge_angle_rad));
  }
  if (!finite_at_least(config.merge_offset_sigmas, 0.0)) {
    return bad("merge_offset_sigmas must be >= 0, got " + std::to_string(config.merge_offset_sigmas));
  }
  if (!finite_at_least(config.merge_offset_floor_m, 0.0)) {
    return bad("merge_offset_floor_m must be >= 0, got " + std::to_string(config.merge_offset_floor_m));
  }
  if (config.min_plane_cells < 1) {
    return bad("min_plane_cells must be >= 1, got " + std::to_string(config.min_plane_cells));
  }
  if (config.max_planes < 1) return bad("max_planes must be >= 1, got " + std::to_string(config.max_planes));
  if (!finite_at_least(noise.sigma0_m, 0.0) || !finite_at_least(noise.k_per_m, 0.0)) {
    return bad("depth noise sigma0_m and k_per_m must be >= 0, got " + std::to_string(noise.sigma0_m) +
               " and " + std::to_string(noise.k_per_m));
  }
  if (grid_width < config.cell_points || grid_height < config.cell_points) {
    return bad("a grid of " + std::to_string(grid_width) + "x" + std::to_string(grid_height) +
               " points is smaller than one cell of cell_points " + std::to_string(config.cell_points));
  }
  return PlaneSegmenter(config, noise, grid_width, grid_height);
}

core::Status PlaneSegmenter::segment(const OrganizedCloud& cloud) {
  if (cloud.width() != grid_width_ || cloud.height() != grid_height_) {
    return core::InvalidArgument("plane segmentation: the cloud is " + std::to_string(cloud.width()) + "x" +
                                 std::to_string(cloud.height()) + " points, the segmenter was created for " +
                                 std::to_string(grid_width_) + "x" + std::to_string(grid_height_));
  }
  // A copy of the segmenter does not keep the reserved capacity; restore it once (create()'s
  // segmenter never takes this branch).
  if (planes_.capacity() < static_cast<size_t>(config_.max_planes)) {
    planes_.reserve(static_cast<size_t>(config_.max_planes));
  }
  const int cp = config_.cell_points;
  const int cells = cells_x_ * cells_y_;
  const double min_valid = config_.cell_min_valid * cp * cp;

  // 1. Cell moments and fits (Feng et al. 2014, sec. III-A: a node is a cell whose points fit one
  // plane). Planar: enough valid points and the RMS within the depth noise at the cell's range. The
  // noise is along the viewing ray, where a distance delta from the plane is delta / |n . r| (r the
  // unit ray to the centroid), so the test is rms <= (k sigma(z) + floor) |n . r|. This also rejects
  // a cell across a depth discontinuity, whose points lie along the rays (n . r ~ 0) in a "shadow
  // plane" that is thin along n (PEAC rejects those with a separate depth-jump test).
  int n_planar = 0;
  for (int cy = 0; cy < cells_y_; ++cy) {
    for (int cx = 0; cx < cells_x_; ++cx) {
      const int i = cy * cells_x_ + cx;
      PlaneMoments m;
      for (int y = cy * cp; y < (cy + 1) * cp; ++y) {
        for (int x = cx * cp; x < (cx + 1) * cp; ++x) {
          if (cloud.valid(x, y)) m.add(cloud.point(x, y).cast<double>());
        }
      }
      cell_moments_[static_cast<size_t>(i)] = m;
      PlaneFit& fit = cell_fit_[static_cast<size_t>(i)];
      fit = m.n >= min_valid ? fit_plane(m) : PlaneFit{};
      const double cos_incidence = std::abs(fit.normal.dot(fit.centroid.normalized()));
      const bool planar =
          fit.ok && fit.rms_m <= (config_.cell_max_rms_sigmas * noise_.sigma_m(fit.centroid.z()) +
                                  config_.cell_rms_floor_m) *
                                     cos_incidence;
      cell_planar_[static_cast<size_t>(i)] = planar ? 1 : 0;
      cell_label_[static_cast<size_t>(i)] = -1;
      if (planar) cell_order_[static_cast<size_t>(n_planar++)] = i;
    }
  }

  // 2. Region growing. PEAC merges the pair of neighbouring nodes whose joint fit is best first;
  // here seeds are taken most planar first (lowest RMS) and a region grows breadth-first over its
  // 4-neighbours, each tested against the region's moments and plane (same_plane), not against the
  // neighbour cell's own fit only: neighbour-to-neighbour tests chain around curves. The region's
  // plane is the joined fit of the last accepted cell.
  std::sort(cell_order_.begin(), cell_order_.begin() + n_planar, [this](int a, int b) {
    const double ra = cell_fit_[static_cast<size_t>(a)].rms_m, rb = cell_fit_[static_cast<size_t>(b)].rms_m;
    return ra != rb ? ra < rb : a < b;
  });
  PlaneMoments joined;
  PlaneFit joined_fit;
  int n_regions = 0;
  for (int s = 0; s < n_planar; ++s) {
    const int seed = cell_order_[static_cast<size_t>(s)];
    if (cell_label_[static_cast<size_t>(seed)] >= 0) continue;
    const int k = n_regions++;
    PlaneRegion& r = regions_[static_cast<size_t>(k)];
    r = PlaneRegion{};
    r.moments = cell_moments_[static_cast<size_t>(seed)];
    r.fit = cell_fit_[static_cast<size_t>(seed)];
    r.cells = 1;
    r.min_cx = r.max_cx = seed % cells_x_;
    r.min_cy = r.max_cy = seed / cells_x_;
    cell_label_[static_cast<size_t>(seed)] = k;
    int head = 0, tail = 0;
    queue_[static_cast<size_t>(tail++)] = seed;
    while (head < tail) {
      const int c = queue_[static_cast<size_t>(head++)];
      const int cx = c % cells_x_, cy = c / cells_x_;
      const int neighbours[4] = {cx > 0 ? c - 1 : -1, cx + 1 < cells_x_ ? c + 1 : -1,
                                 cy > 0 ? c - cells_x_ : -1, cy + 1 < cells_y_ ? c + cells_x_ : -1};
      for (const int q : neighbours) {
        if (q < 0 || !cell_planar_[static_cast<size_t>(q)] || cell_label_[static_cast<size_t>(q)] >= 0)
          continue;
        if (!same_plane(r.moments, r.fit, cell_moments_[static_cast<size_t>(q)],
                        cell_fit_[static_cast<size_t>(q)], config_, noise_, &joined_fit, &joined)) {
          continue;
        }
        cell_label_[static_cast<size_t>(q)] = k;
        r.moments = joined;
        r.fit = joined_fit;
        ++r.cells;
        include_cell(q % cells_x_, q / cells_x_, &r);
        queue_[static_cast<size_t>(tail++)] = q;
      }
    }
  }

  // 3. Joining adjacent regions. Growth from a seed whose own plane is noisy can stop early and
  // leave one surface in fragments; adjacent regions that pass same_plane are joined (union-find
  // over regions, each union folded into the root at once, so later tests see the joined region).
  // cell_order_ is free now and holds the parents; roots are the smallest index of their set.
  int* parent = cell_order_.data();
  for (int k = 0; k < n_regions; ++k) parent[k] = k;
  const auto find = [parent](int k) {
    while (parent[k] != k) {
      parent[k] = parent[parent[k]];
      k = parent[k];
    }
    return k;
  };
  const auto join_if_same_plane = [&](int a, int b) {
    if (a < 0 || b < 0) return;
    const int ra = find(a), rb = find(b);
    if (ra == rb) return;
    PlaneRegion& into = regions_[static_cast<size_t>(std::min(ra, rb))];
    PlaneRegion& from = regions_[static_cast<size_t>(std::max(ra, rb))];
    if (!same_plane(into.moments, into.fit, from.moments, from.fit, config_, noise_, &joined_fit, &joined))
      return;
    into.moments = joined;
    into.fit = joined_fit;
    into.cells += from.cells;
    include_cell(from.min_cx, from.min_cy, &into);
    include_cell(from.max_cx, from.max_cy, &into);
    from.cells = 0;
    parent[std::max(ra, rb)] = std::min(ra, rb);
  };
  for (int cy = 0; cy < cells_y_; ++cy) {
    for (int cx = 0; cx < cells_x_; ++cx) {
      const int l = cell_label(cx, cy);
      if (l < 0) continue;
      if (cx + 1 < cells_x_) join_if_same_plane(l, cell_label(cx + 1, cy));
      if (cy + 1 < cells_y_) join_if_same_plane(l, cell_label(cx, cy + 1));
    }
  }
  for (int i = 0; i < cells; ++i) {
    int& label = cell_label_[static_cast<size_t>(i)];
    if (label >= 0) label = find(label);
  }

  // 4. Planes: regions of at least min_plane_cells cells that hold a 2x2 block of their cells (a
  // strip one cell wide is the row of cells along a crease, each bent a little the same way, not a
  // surface), the largest first. plane_of_region_ first marks the regions with a block; queue_
  // holds the candidates' order.
  std::fill(plane_of_region_.begin(), plane_of_region_.begin() + n_regions, 0);
  for (int cy = 0; cy + 1 < cells_y_; ++cy) {
    for (int cx = 0; cx + 1 < cells_x_; ++cx) {
      const int l = cell_label(cx, cy);
      if (l >= 0 && cell_label(cx + 1, cy) == l && cell_label(cx, cy + 1) == l &&
          cell_label(cx + 1, cy + 1) == l) {
        plane_of_region_[static_cast<size_t>(l)] = 1;
      }
    }
  }
  int n_candidates = 0;
  for (int k = 0; k < n_regions; ++k) {
    const PlaneRegion& r = regions_[static_cast<size_t>(k)];
    if (r.cells >= config_.min_plane_cells && plane_of_region_[static_cast<size_t>(k)] && r.fit.ok) {
      queue_[static_cast<size_t>(n_candidates++)] = k;
    }
  }
  std::sort(queue_.begin(), queue_.begin() + n_candidates, [this](int a, int b) {
    const int ca = regions_[static_cast<size_t>(a)].cells, cb = regions_[static_cast<size_t>(b)].cells;
    return ca != cb ? ca > cb : a < b;
  });
  std::fill(plane_of_region_.begin(), plane_of_region_.begin() + n_regions, -1);
  planes_.clear();
  for (int j = 0; j < n_candidates && j < config_.max_planes; ++j) {
    const int k = queue_[static_cast<size_t>(j)];
    plane_of_region_[static_cast<size_t>(k)] = j;
    planes_.push_back(regions_[static_cast<size_t>(k)]);
  }
  for (int i = 0; i < cells; ++i) {
    int& label = cell_label_[static_cast<size_t>(i)];
    if (label >= 0) label = plane_of_region_[static_cast<size_t>(label)];
  }

  // 5. Point labels. A plane's cells stop one cell short of its border (a cell across an edge is not
  // planar); the valid points of those cells join the nearest plane of a neighbouring cell within
  // its noise (design section 3.2c).
  const int all_cx = (grid_width_ + cp - 1) / cp, all_cy = (grid_height_ + cp - 1) / cp;
  for (int gy = 0; gy < all_cy; ++gy) {
    for (int gx = 0; gx < all_cx; ++gx) {
      const int x0 = gx * cp, x1 = std::min(x0 + cp, grid_width_);
      const int y0 = gy * cp, y1 = std::min(y0 + cp, grid_height_);
      const int own = gx < cells_x_ && gy < cells_y_ ? cell_label(gx, gy) : -1;
      int near_planes[8];
      int n_near = 0;
      if (own < 0) {
        for (int dy = -1; dy <= 1; ++dy) {
          for (int dx = -1; dx <= 1; ++dx) {
            const int nx = gx + dx, ny = gy + dy;
            if ((dx == 0 && dy == 0) || nx < 0 || ny < 0 || nx >= cells_x_ || ny >= cells_y_) continue;
            const int l = cell_label(nx, ny);
            if (l < 0 || std::find(near_planes, near_planes + n_near, l) != near_planes + n_near) continue;
            near_planes[n_near++] = l;
          }
        }
      }
      for (int y = y0; y < y1; ++y) {
        int* labels = point_label_.data() + static_cast<size_t>(y) * grid_width_;
        for (int x = x0; x < x1; ++x) {
          if (!cloud.valid(x, y)) {
            labels[x] = -1;
            continue;
          }
          if (own >= 0) {
            labels[x] = own;
            continue;
          }
          const Eigen::Vector3d p = cloud.point(x, y).cast<double>();
          const double limit =
              config_.merge_offset_sigmas * noise_.sigma_m(p.z()) + config_.merge_offset_floor_m;
          int best = -1;
          double best_distance = limit;
          for (int c = 0; c < n_near; ++c) {
            const double distance =
                std::abs(planes_[static_cast<size_t>(near_planes[c])].fit.signed_distance(p));
            if (distance <= best_distance) {
              best_distance = distance;
              best = near_planes[c];
            }
          }
          labels[x] = best;
        }
      }
    }
  }
  return core::Status::Ok();
}

}  // namespace hwr::detect
