#include "hwr/recon/fine_region_map.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <utility>

#include "hwr/core/se3.hpp"

namespace hwr::recon {
namespace {

// The 8 corners of a box of half sizes `half` centred at the origin of its frame.
Eigen::Vector3d box_corner(const Eigen::Vector3d& half, int i) {
  return Eigen::Vector3d((i & 4) ? half.x() : -half.x(), (i & 2) ? half.y() : -half.y(),
                         (i & 1) ? half.z() : -half.z());
}

// Pixel rectangle [u0, u1) x [v0, v1) of the image that a box (T_cam_box, half) can cover at depths in
// [min_z, max_z]; false when it covers none. z is linear over the box, so its extremes are at corners.
// A box reaching behind the camera's near plane is given the whole image.
bool box_pixels(const Eigen::Isometry3d& T_cam_box, const Eigen::Vector3d& half,
                const hal::PinholeIntrinsics& K, double min_z, double max_z, cv::Rect* rect) {
  double z_lo = std::numeric_limits<double>::infinity(), z_hi = -z_lo;
  double u_lo = z_lo, u_hi = z_hi, v_lo = z_lo, v_hi = z_hi;
  bool behind = false;
  for (int i = 0; i < 8; ++i) {
    const Eigen::Vector3d c = T_cam_box * box_corner(half, i);
    z_lo = std::min(z_lo, c.z());
    z_hi = std::max(z_hi, c.z());
    if (!(c.z() >= std::max(min_z, 1e-6))) {  // also z = 0 when min_z is 0: no projection
      behind = true;
      continue;
    }
    const double u = K.fx * c.x() / c.z() + K.cx, v = K.fy * c.y() / c.z() + K.cy;
    u_lo = std::min(u_lo, u), u_hi = std::max(u_hi, u);
    v_lo = std::min(v_lo, v), v_hi = std::max(v_hi, v);
  }
  if (z_lo > max_z || z_hi < min_z) return false;
  if (behind) {
    *rect = cv::Rect(0, 0, K.width, K.height);
    return true;
  }
  // Pixel centres at integer coordinates: pixel u covers [u - 0.5, u + 0.5).
  // Clamped in double first: a corner just in front of the camera projects far beyond int's range.
  const double w = K.width, h = K.height;
  const int u0 = static_cast<int>(std::clamp(std::floor(u_lo), 0.0, w)),
            v0 = static_cast<int>(std::clamp(std::floor(v_lo), 0.0, h));
  const int u1 = static_cast<int>(std::clamp(std::ceil(u_hi) + 1, 0.0, w));
  const int v1 = static_cast<int>(std::clamp(std::ceil(v_hi) + 1, 0.0, h));
  if (u0 >= u1 || v0 >= v1) return false;
  *rect = cv::Rect(u0, v0, u1 - u0, v1 - v0);
  return true;
}

// A box with positive finite half sizes and a rigid pose.
bool valid_box(const Eigen::Isometry3d& T_world_region, const Eigen::Vector3d& h) {
  return h.allFinite() && h.minCoeff() > 0 && core::rigid_transform_problem(T_world_region).empty();
}

// A merged detection this much nearer to its camera than the region's anchor re-anchors it.
constexpr double kReanchorM = 0.05;

}  // namespace

FineRegionMap::FineRegionMap(const FineRegionConfig& config, const hal::PinholeIntrinsics& K, VoxelMap map)
    : config_(config),
      K_(K),
      map_(std::move(map)),
      // The keyframe's cloud and the part of it inside the regions (at most as many points).
      arena_(std::make_unique<core::Arena>(
          config.enabled ? 2 * keyframe_cloud_capacity_bytes(K.width, K.height, config.cloud) : 0)) {
  active_.reserve(static_cast<size_t>(config.max_regions));
}

FineRegionMap::FineRegionMap(FineRegionMap&&) noexcept = default;
FineRegionMap& FineRegionMap::operator=(FineRegionMap&&) noexcept = default;
FineRegionMap::~FineRegionMap() = default;

core::Expected<FineRegionMap> FineRegionMap::create(const FineRegionConfig& config,
                                                    const hal::PinholeIntrinsics& K) {
  if (!K.valid()) return core::InvalidArgument("fine region map: invalid intrinsics");
  const KeyframeCloudConfig& c = config.cloud;
  if (c.stride_px < 1 || !(c.min_depth_m >= 0) || !(c.max_depth_m > c.min_depth_m) ||
      !(c.max_depth_step > 0)) {
    return core::InvalidArgument(
        "fine region map: cloud needs stride_px >= 1, 0 <= min_depth_m < max_depth_m, max_depth_step > 0");
  }
  if (config.max_regions < 1) {
    return core::InvalidArgument("fine region map: max_regions must be >= 1, got " +
                                 std::to_string(config.max_regions));
  }
  if (!(config.max_cover_m > 0) || !(config.cover_max_angle_rad >= 0)) {
    return core::InvalidArgument("fine region map: max_cover_m must be positive, cover_max_angle_rad >= 0");
  }
  auto map = VoxelMap::create(config.voxels);
  if (!map.ok()) return core::InvalidArgument("fine region map: " + map.status().message());
  return FineRegionMap(config, K, std::move(map.value()));
}

int64_t FineRegionMap::add(const WeldRegion& detection, const Eigen::Isometry3d& T_world_cam) {
  const Eigen::Vector3d& h = detection.half_size_m;
  if (!(h.allFinite() && h.minCoeff() > 0) ||
      !core::rigid_transform_problem(detection.T_cam_region).empty() ||
      !core::rigid_transform_problem(T_world_cam).empty()) {
    ++counters_.detections_invalid;
    return -1;
  }
  const Eigen::Isometry3d T_world_region = T_world_cam * detection.T_cam_region;
  const Eigen::Vector3d centre = T_world_region.translation();
  for (Active& a : active_) {
    const bool ours = inside_region_box(a.T_region_world * centre, a.region.half_size_m);
    const bool theirs =
        inside_region_box(T_world_region.inverse(Eigen::Isometry) * a.T_world_region.translation(), h);
    if (!ours && !theirs) continue;
    ++counters_.detections_merged;
    if (a.fixed) return a.region.id;  // the operator's box stays as it was drawn
    // The box the anchor does not keep: the detection's, or the region's own when re-anchored.
    Eigen::Isometry3d T_world_other = T_world_region;
    Eigen::Vector3d h_other = h;
    if (detection.T_cam_region.translation().norm() + kReanchorM <
        a.region.T_cam_region.translation().norm()) {
      T_world_other = a.T_world_region;
      h_other = a.region.half_size_m;
      const uint32_t id = a.region.id;
      a.region = detection;
      a.region.id = id;
      a.T_world_region = T_world_region;
      a.T_region_world = T_world_region.inverse(Eigen::Isometry);
      ++counters_.anchors_moved;
    }
    if (config_.grow_to_cover) cover(&a, T_world_other, h_other);
    return a.region.id;
  }
  if (static_cast<int>(active_.size()) >= config_.max_regions) {
    ++counters_.regions_refused;
    return -1;
  }
  Active a;
  a.region = detection;
  a.region.id = next_id_++;
  a.T_world_region = T_world_region;
  a.T_region_world = T_world_region.inverse(Eigen::Isometry);
  active_.push_back(a);  // within the reserved capacity: no allocation
  ++counters_.regions_added;
  return a.region.id;
}

void FineRegionMap::cover(Active* a, const Eigen::Isometry3d& T_world_other, const Eigen::Vector3d& h_other) {
  // The axis-aligned hull, in the region's axes, of its box and the other box's corners.
  Eigen::Vector3d lo = -a->region.half_size_m, hi = a->region.half_size_m;
  const Eigen::Isometry3d T_region_other = a->T_region_world * T_world_other;
  if (std::fabs(T_region_other.linear()(0, 0)) < std::cos(config_.cover_max_angle_rad))
    return;  // another direction
  for (int i = 0; i < 8; ++i) {
    const Eigen::Vector3d corner((i & 4 ? 1 : -1) * h_other.x(), (i & 2 ? 1 : -1) * h_other.y(),
                                 (i & 1 ? 1 : -1) * h_other.z());
    const Eigen::Vector3d c = T_region_other * corner;
    lo = lo.cwiseMin(c);
    hi = hi.cwiseMax(c);
  }
  if ((hi - lo).maxCoeff() > config_.max_cover_m) return;  // not one joint: keep the box
  const Eigen::Vector3d offset_region = 0.5 * (lo + hi);
  a->region.half_size_m = 0.5 * (hi - lo);
  a->region.T_cam_region.translation() += a->region.T_cam_region.linear() * offset_region;
  a->T_world_region.translation() += a->T_world_region.linear() * offset_region;
  a->T_region_world = a->T_world_region.inverse(Eigen::Isometry);
  ++counters_.boxes_grown;
}

int FineRegionMap::find(uint32_t id) const {
  for (size_t i = 0; i < active_.size(); ++i)
    if (active_[i].region.id == id) return static_cast<int>(i);
  return -1;
}

int64_t FineRegionMap::add_fixed(const WeldRegion& region, const Eigen::Isometry3d& T_world_region) {
  if (!valid_box(T_world_region, region.half_size_m)) {
    ++counters_.detections_invalid;
    return -1;
  }
  if (static_cast<int>(active_.size()) >= config_.max_regions) {
    ++counters_.regions_refused;
    return -1;
  }
  Active a;
  a.region = region;
  a.region.id = next_id_++;
  a.fixed = true;
  a.T_world_region = T_world_region;
  a.T_region_world = T_world_region.inverse(Eigen::Isometry);
  active_.push_back(a);  // within the reserved capacity: no allocation
  ++counters_.regions_added;
  ++counters_.boxes_fixed;
  return a.region.id;
}

bool FineRegionMap::set_fixed_box(uint32_t id, const Eigen::Isometry3d& T_world_region,
                                  const Eigen::Vector3d& half_size_m) {
  const int i = find(id);
  if (i < 0 || !valid_box(T_world_region, half_size_m)) return false;
  Active& a = active_[static_cast<size_t>(i)];
  a.fixed = true;
  a.region.half_size_m = half_size_m;
  a.T_world_region = T_world_region;
  a.T_region_world = T_world_region.inverse(Eigen::Isometry);
  ++counters_.boxes_fixed;
  return true;
}

bool FineRegionMap::remove(uint32_t id) {
  const int i = find(id);
  if (i < 0) return false;
  active_.erase(active_.begin() + i);  // shifts within the capacity: no allocation
  ++counters_.regions_removed;
  return true;
}

void FineRegionMap::settle(int32_t keyframe_id, const Eigen::Isometry3d& T_world_cam) {
  for (Active& a : active_) {
    if (a.fixed || a.region.keyframe_id != keyframe_id) continue;
    a.T_world_region = T_world_cam * a.region.T_cam_region;
    a.T_region_world = a.T_world_region.inverse(Eigen::Isometry);
  }
}

void FineRegionMap::insert_keyframe(const cv::Mat& bgr, const cv::Mat& depth_m,
                                    const Eigen::Isometry3d& T_world_cam,
                                    const Eigen::Isometry3d& T_world_segment) {
  if (!config_.enabled || active_.empty() || depth_m.empty()) return;
  const Eigen::Isometry3d T_cam_world = T_world_cam.inverse(Eigen::Isometry);
  const Eigen::Isometry3d T_segment_cam = T_world_segment.inverse(Eigen::Isometry) * T_world_cam;
  cv::Rect all;
  bool any = false;
  for (Active& a : active_) {
    cv::Rect r;
    a.in_view = box_pixels(T_cam_world * a.T_world_region, a.region.half_size_m, K_,
                           config_.cloud.min_depth_m, config_.cloud.max_depth_m, &r);
    if (!a.in_view) continue;
    a.T_region_segment = a.T_region_world * T_world_segment;
    a.keyframe_points = 0;
    all = any ? (all | r) : r;
    any = true;
  }
  if (!any) return;
  ++counters_.keyframes_in_view;
  if (depth_m.cols != K_.width || depth_m.rows != K_.height ||
      (!bgr.empty() && bgr.size() != depth_m.size())) {
    ++counters_.cloud_errors;
    return;
  }
  // The rectangle as an image of its own: the same pinhole with the principal point moved.
  hal::PinholeIntrinsics K_rect = K_;
  K_rect.width = all.width;
  K_rect.height = all.height;
  K_rect.cx -= all.x;
  K_rect.cy -= all.y;
  arena_->reset();
  auto cloud = build_keyframe_cloud(bgr.empty() ? cv::Mat() : bgr(all), depth_m(all), K_rect, T_segment_cam,
                                    config_.cloud, arena_.get());
  if (!cloud.ok()) {
    ++counters_.cloud_errors;
    return;
  }
  CloudPoint* kept = arena_->allocate<CloudPoint>(static_cast<size_t>(std::max(cloud->size, 1)));
  if (kept == nullptr) {
    ++counters_.cloud_errors;
    return;
  }
  int n = 0;
  for (int i = 0; i < cloud->size; ++i) {
    const CloudPoint& p = cloud->points[i];
    const Eigen::Vector3d p_segment(p.x_m, p.y_m, p.z_m);
    for (Active& a : active_) {
      if (a.in_view && inside_region_box(a.T_region_segment * p_segment, a.region.half_size_m)) {
        kept[n++] = p;
        ++a.keyframe_points;
        break;
      }
    }
  }
  const Eigen::Vector3d camera_segment = T_segment_cam.translation();
  for (Active& a : active_) {
    if (!a.in_view || a.keyframe_points == 0) continue;
    a.viewpoint_sum += static_cast<double>(a.keyframe_points) * camera_segment;
    a.viewpoint_points += a.keyframe_points;
  }
  map_.insert(kept, n);
  counters_.points_inserted += static_cast<uint64_t>(n);
}

void FineRegionMap::take_segment(const Eigen::Isometry3d& T_world_segment,
                                 std::vector<CloudPoint>* points_segment, std::vector<uint32_t>* counts,
                                 std::vector<StoredWeldRegion>* regions) {
  points_segment->clear();
  counts->clear();
  regions->clear();
  points_segment->reserve(static_cast<size_t>(map_.size()));
  counts->reserve(static_cast<size_t>(map_.size()));
  for (Active& a : active_) {
    a.segment_points = 0;
    a.T_region_segment = a.T_region_world * T_world_segment;
  }
  for (int i = 0; i < map_.size(); ++i) {
    const Voxel& v = map_.at_slot(map_.created(i));
    CloudPoint p;
    p.x_m = v.x_m;
    p.y_m = v.y_m;
    p.z_m = v.z_m;
    p.r = static_cast<uint8_t>(std::clamp(std::lround(v.r), 0L, 255L));
    p.g = static_cast<uint8_t>(std::clamp(std::lround(v.g), 0L, 255L));
    p.b = static_cast<uint8_t>(std::clamp(std::lround(v.b), 0L, 255L));
    points_segment->push_back(p);
    counts->push_back(v.count);
    const Eigen::Vector3d q(v.x_m, v.y_m, v.z_m);
    for (Active& a : active_)
      if (inside_region_box(a.T_region_segment * q, a.region.half_size_m)) ++a.segment_points;
  }
  const Eigen::Isometry3d T_segment_world = T_world_segment.inverse(Eigen::Isometry);
  for (const Active& a : active_) {
    if (a.segment_points == 0) continue;
    StoredWeldRegion s;
    s.region = a.region;
    s.T_segment_region = T_segment_world * a.T_world_region;
    s.fine_points = a.segment_points;
    if (a.viewpoint_points > 0)
      s.viewpoint_segment = a.viewpoint_sum / static_cast<double>(a.viewpoint_points);
    regions->push_back(s);
  }
  for (Active& a : active_) {
    a.viewpoint_sum.setZero();
    a.viewpoint_points = 0;
  }
  map_.clear();
}

}  // namespace hwr::recon
