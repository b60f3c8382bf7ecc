#include "hwr/recon/prior_map.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>

#include "hwr/core/log.hpp"
#include "hwr/recon/cloud_thinning.hpp"
#include "hwr/estimation/descriptor.hpp"

namespace hwr::recon {
namespace {

// Rebuilds one stored keyframe's features (eq. 3 back-projection where the depth is valid).
estimation::FrameFeatures to_frame_features(const StoredKeyframe& kf, const hal::PinholeIntrinsics& K,
                                            const PriorMapConfig& config) {
  const int n = static_cast<int>(kf.features.size());
  estimation::FrameFeatures f(std::max(n, 1), K.width, K.height, config.orb_levels, config.orb_scale_factor);
  for (int i = 0; i < n; ++i) {
    const StoredFeature& s = kf.features[static_cast<size_t>(i)];
    estimation::Feature e;
    e.u_px = s.u_px;
    e.v_px = s.v_px;
    e.octave = s.octave;
    if (std::isfinite(s.depth_m) && s.depth_m > 0) {
      e.depth_m = s.depth_m;
      // Eq. (3), in float pixel coordinates as GridOrbExtractor computes it.
      e.p_cam_m =
          Eigen::Vector3d((s.u_px - K.cx) * s.depth_m / K.fx, (s.v_px - K.cy) * s.depth_m / K.fy, s.depth_m);
    }
    f.push_back(e, &kf.descriptors[static_cast<size_t>(i) * estimation::kOrbDescriptorBytes]);
  }
  f.build_grid();
  return f;
}

double distance_to_box(const Eigen::AlignedBox3d& box, const Eigen::Vector3d& p) {
  if (box.isEmpty()) return std::numeric_limits<double>::infinity();
  return std::sqrt(box.squaredExteriorDistance(p));
}

}  // namespace

core::Expected<PriorMap> PriorMap::open(const std::string& dir, const PriorMapConfig& config) {
  if (!(config.max_loaded_points >= 1) || !(config.max_prior_features >= 1) || !(config.cloud_reach_m >= 0) ||
      !std::isfinite(config.cloud_reach_m) || config.orb_levels < 1 || !(config.orb_scale_factor >= 1.0f) ||
      !(config.cloud_voxel_m >= 0) || !std::isfinite(config.cloud_voxel_m)) {
    return core::InvalidArgument(
        "prior map: max_loaded_points and max_prior_features must be >= 1, cloud_reach_m and cloud_voxel_m "
        "finite and >= 0, orb_levels >= 1 and orb_scale_factor >= 1");
  }
  auto store = MapStore::open_existing(dir);
  if (!store.ok()) return core::Status(store.status().code(), "prior map: " + store.status().message());
  const StoreMetadata& meta = store->metadata();
  if (meta.descriptor_bytes != estimation::kOrbDescriptorBytes) {
    return core::InvalidArgument("prior map " + dir + ": descriptor_bytes is " +
                                 std::to_string(meta.descriptor_bytes) + ", the relocalizer matches " +
                                 std::to_string(estimation::kOrbDescriptorBytes) + "-byte ORB descriptors");
  }
  if (!meta.intrinsics.valid()) {
    return core::InvalidArgument("prior map " + dir + ": store.yaml holds invalid intrinsics");
  }
  auto list = store->list_segments();
  if (!list.ok()) return core::Status(list.status().code(), "prior map: " + list.status().message());
  if (list->empty()) {
    return core::NotFound("prior map " + dir +
                          ": the store holds no complete segment; nothing to relocalize in");
  }

  PriorMap map(std::move(store).value(), config);
  static std::atomic<uint64_t> next_instance{1};
  map.instance_id_ = next_instance.fetch_add(1);
  map.segments_.reserve(list->size());
  int64_t total_features = 0;
  for (const SegmentSummary& summary : *list) {
    auto rec = map.store_.read_keyframes(summary.segment_id);
    if (!rec.ok()) return core::Status(rec.status().code(), "prior map: " + rec.status().message());
    // The memory bound (header, "Memory"), checked before this segment's features are kept.
    for (const StoredKeyframe& kf : rec->keyframes)
      total_features += static_cast<int64_t>(kf.features.size());
    if (total_features > config.max_prior_features) {
      return core::OutOfRange(
          "prior map " + dir + ": more than " + std::to_string(config.max_prior_features) +
          " keyframe features (at least " + std::to_string(total_features) + " by segment " +
          std::to_string(summary.segment_id) + " of " + std::to_string(list->size()) +
          ", ~190 bytes each held while relocalizing); raise PriorMapConfig::max_prior_features if the "
          "memory is there, or give a smaller prior map");
    }
    PriorSegment seg;
    seg.segment_id = summary.segment_id;
    seg.T_prior_segment = rec->T_world_segment;
    seg.first_keyframe = static_cast<int>(map.keyframes_.size());
    seg.keyframe_count = static_cast<int>(rec->keyframes.size());
    seg.points = summary.points;
    seg.keyframe_box_prior.setEmpty();
    for (const StoredKeyframe& kf : rec->keyframes) {
      if (!kf.T_world_cam.matrix().allFinite()) {
        return core::CorruptData("prior map " + dir + ": segment " + std::to_string(summary.segment_id) +
                                 ", keyframe " + std::to_string(kf.id) + ": non-finite pose");
      }
      PriorKeyframe pk(to_frame_features(kf, meta.intrinsics, config));
      pk.segment_id = summary.segment_id;
      pk.id = kf.id;
      pk.t_ns = kf.t_ns;
      pk.T_prior_cam = kf.T_world_cam;
      pk.gnss_valid = kf.gnss_valid;
      pk.lat_deg = kf.lat_deg;
      pk.lon_deg = kf.lon_deg;
      pk.alt_m = kf.alt_m;
      pk.mag_valid = kf.mag_valid;
      pk.mag_imu_uT = kf.mag_imu_uT;
      map.max_features_ = std::max(map.max_features_, pk.features.size());
      seg.keyframe_box_prior.extend(kf.T_world_cam.translation());
      map.keyframes_.push_back(std::move(pk));
    }
    map.segments_.push_back(seg);
  }
  map.clouds_prior_.resize(map.segments_.size());
  map.last_used_.assign(map.segments_.size(), 0);
  map.needed_.assign(map.segments_.size(), 0);
  map.near_.reserve(map.segments_.size());
  return map;
}

double PriorMap::box_distance_m(const PriorSegment& s, const Eigen::Vector3d& p) const {
  if (s.cloud_box_known) return distance_to_box(s.cloud_box_prior, p);
  if (s.keyframe_box_prior.isEmpty()) return std::numeric_limits<double>::infinity();
  Eigen::AlignedBox3d grown = s.keyframe_box_prior;
  const Eigen::Vector3d reach = Eigen::Vector3d::Constant(config_.cloud_reach_m);
  grown.min() -= reach;
  grown.max() += reach;
  return distance_to_box(grown, p);
}

void PriorMap::evict(size_t index) {
  PriorSegment& s = segments_[index];
  if (!s.loaded) return;
  counters_.loaded_points -= static_cast<int64_t>(clouds_prior_[index].size());
  --counters_.loaded_segments;
  std::vector<CloudPoint>().swap(clouds_prior_[index]);  // release the memory
  s.loaded = false;
  ++cloud_generation_;
  ++counters_.cloud_evictions;
}

void PriorMap::make_room(int64_t extra_points) {
  while (counters_.loaded_points + extra_points > config_.max_loaded_points) {
    size_t victim = segments_.size();
    for (size_t j = 0; j < segments_.size(); ++j) {
      if (!segments_[j].loaded || needed_[j]) continue;
      if (victim == segments_.size() || last_used_[j] < last_used_[victim]) victim = j;
    }
    if (victim == segments_.size()) return;
    evict(victim);
  }
}

void PriorMap::mark_unreadable(size_t index, const core::Status& why) {
  // One damaged cloud must not stop every query over it: skip it from now on, say so once.
  PriorSegment& s = segments_[index];
  s.unreadable = true;
  ++cloud_generation_;
  ++counters_.unreadable_segments;
  HWR_LOG_WARN("prior-map", "segment %u: cloud unreadable, skipped from now on: %s", s.segment_id,
               why.message().c_str());
}

void PriorMap::drop_unbudgeted(size_t index) {
  evict(index);
  --counters_.cloud_evictions;  // not a cache eviction: it never was within the budget
}

core::Status PriorMap::load_cloud(size_t index) {
  PriorSegment& s = segments_[index];
  auto rec = store_.read_cloud(s.segment_id);  // the points only: not keyframes.bin, not fine.bin
  if (!rec.ok()) return core::Status(rec.status().code(), "prior map: " + rec.status().message());
  std::vector<CloudPoint>& cloud = clouds_prior_[index];
  cloud = std::move(rec->points_segment);
  if (config_.cloud_voxel_m > 0) {
    // Thinned in the segment frame, where the map's voxels were (PriorMapConfig::cloud_voxel_m).
    auto thinned = thin_cloud(&cloud, config_.cloud_voxel_m);
    if (!thinned.ok()) {
      std::vector<CloudPoint>().swap(cloud);  // never left in memory unthinned, in the segment frame
      return thinned.status();
    }
    counters_.points_read += thinned->points_in;
  } else {
    counters_.points_read += static_cast<int64_t>(cloud.size());
  }
  // Segment frame -> prior frame, once at load (the points are then searched and copied as they are).
  const Eigen::Isometry3f T = s.T_prior_segment.cast<float>();
  Eigen::AlignedBox3d box;
  box.setEmpty();
  for (CloudPoint& p : cloud) {
    const Eigen::Vector3f q = T * Eigen::Vector3f(p.x_m, p.y_m, p.z_m);
    p.x_m = q.x();
    p.y_m = q.y();
    p.z_m = q.z();
    if (q.allFinite()) box.extend(q.cast<double>());
  }
  s.cloud_box_prior = box;
  s.cloud_box_known = true;
  s.points = static_cast<int64_t>(cloud.size());
  s.loaded = true;
  ++cloud_generation_;
  counters_.loaded_points += s.points;
  ++counters_.loaded_segments;
  ++counters_.cloud_loads;
  return core::Status::Ok();
}

bool PriorMap::all_clouds_in_memory() const {
  for (const PriorSegment& s : segments_) {
    if (!s.loaded && !s.unreadable) return false;
  }
  return true;
}

PreloadStats PriorMap::preload_clouds(const std::function<bool()>& keep_going) {
  PreloadStats stats;
  for (size_t i = 0; i < segments_.size(); ++i) {
    PriorSegment& s = segments_[i];
    if (s.loaded || s.unreadable) continue;
    if (keep_going && !keep_going()) {
      stats.cancelled = true;  // the rest stay on disk; points_near reads them when needed
      break;
    }
    // s.points is segment.yaml's count until read: thinned, the cloud is smaller, so try it.
    const core::Status st = load_cloud(i);
    if (!st.ok()) {
      mark_unreadable(i, st);
      ++stats.segments_unreadable;
      continue;
    }
    if (counters_.loaded_points > config_.max_loaded_points) {
      // Full: this and the rest stay on disk (a large map is not read through to find small clouds).
      drop_unbudgeted(i);
      for (size_t j = i; j < segments_.size(); ++j) {
        stats.segments_over_budget += (!segments_[j].loaded && !segments_[j].unreadable) ? 1 : 0;
      }
      break;
    }
    last_used_[i] = 0;  // least recently used: the first to go when a query needs room
    ++stats.segments_loaded;
  }
  for (const PriorSegment& s : segments_) stats.segments_in_memory += s.loaded ? 1 : 0;
  stats.points_in_memory = counters_.loaded_points;
  return stats;
}

core::Expected<PointsNearStats> PriorMap::points_near(const Eigen::Vector3d& p_prior_m, double radius_m,
                                                      std::vector<CloudPoint>* out) {
  out->clear();
  if (!(radius_m > 0) || !std::isfinite(radius_m) || !p_prior_m.allFinite()) {
    return core::InvalidArgument(
        "prior map: points_near needs a finite position and a positive, finite radius");
  }
  ++counters_.queries;
  const uint64_t stamp = ++stamp_;
  PointsNearStats stats;
  near_.clear();
  std::fill(needed_.begin(), needed_.end(), 0);
  for (size_t i = 0; i < segments_.size(); ++i) {
    const double d = box_distance_m(segments_[i], p_prior_m);
    if (d <= radius_m) {
      near_.emplace_back(d, i);
      needed_[i] = 1;
    }
  }
  std::sort(near_.begin(), near_.end());
  stats.segments_near = static_cast<int>(near_.size());

  const float r2 = static_cast<float>(radius_m * radius_m);
  const Eigen::Vector3f c = p_prior_m.cast<float>();
  for (const auto& [distance, index] : near_) {
    (void)distance;
    PriorSegment& s = segments_[index];
    if (s.unreadable) {
      ++stats.segments_unreadable;
      needed_[index] = 0;
      continue;
    }
    if (!s.loaded) {
      // Make room: evict least-recently-used clouds this query does not need. A cloud's size is known
      // once it was read (thinned); before that it is read first and room is made after (the
      // "one segment being read" of the header), so that segment.yaml's unthinned count neither
      // evicts clouds needlessly nor keeps a cloud out that fits thinned.
      const bool size_known = s.cloud_box_known || config_.cloud_voxel_m <= 0;
      if (size_known) {
        make_room(s.points);
        if (counters_.loaded_points + s.points > config_.max_loaded_points) {
          ++stats.segments_over_budget;
          needed_[index] = 0;
          continue;
        }
      }
      const core::Status st = load_cloud(index);
      if (!st.ok()) {
        mark_unreadable(index, st);
        ++stats.segments_unreadable;
        needed_[index] = 0;
        continue;
      }
      if (!size_known) {
        make_room(0);
        if (counters_.loaded_points > config_.max_loaded_points) {
          drop_unbudgeted(index);
          ++stats.segments_over_budget;
          needed_[index] = 0;
          continue;
        }
      }
      // The exact box may show the cloud is not near after all: then this query does not need it
      // (it may be evicted to make room for a segment that is near).
      if (box_distance_m(s, p_prior_m) > radius_m) {
        last_used_[index] = stamp;
        needed_[index] = 0;
        continue;
      }
    }
    last_used_[index] = stamp;
    ++stats.segments_used;
    for (const CloudPoint& p : clouds_prior_[index]) {
      const float dx = p.x_m - c.x(), dy = p.y_m - c.y(), dz = p.z_m - c.z();
      if (dx * dx + dy * dy + dz * dz <= r2) out->push_back(p);
    }
  }
  stats.points = static_cast<int64_t>(out->size());
  return stats;
}

}  // namespace hwr::recon
