#include "hwr/recon/local_mapper.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <utility>

#include "hwr/core/log.hpp"

namespace hwr::recon {
namespace {

StoredKeyframe stored_keyframe(const estimation::Keyframe* kf, int id, const Eigen::Isometry3d& T_world_cam,
                               int64_t t_ns) {
  StoredKeyframe s;
  s.id = id;
  s.t_ns = t_ns;
  s.T_world_cam = T_world_cam;
  if (kf == nullptr) return s;
  const int n = kf->features.size();
  s.features.resize(static_cast<size_t>(n));
  s.descriptors.resize(static_cast<size_t>(n) * estimation::kOrbDescriptorBytes);
  for (int i = 0; i < n; ++i) {
    const estimation::Feature& f = kf->features.feature(i);
    StoredFeature& o = s.features[static_cast<size_t>(i)];
    o.u_px = f.u_px;
    o.v_px = f.v_px;
    o.depth_m = f.depth_m;
    o.octave = static_cast<uint8_t>(std::clamp(f.octave, 0, 255));
    std::copy_n(kf->features.descriptor(i), estimation::kOrbDescriptorBytes,
                s.descriptors.begin() + static_cast<ptrdiff_t>(i) * estimation::kOrbDescriptorBytes);
  }
  return s;
}

PointsView view_of(const KeyframeCloud& c) {
  PointsView v;
  v.xyz = c.size > 0 ? &c.points[0].x_m : nullptr;
  v.n = c.size;
  v.stride_floats = sizeof(CloudPoint) / sizeof(float);
  return v;
}

uint8_t to_u8(float v) { return static_cast<uint8_t>(std::clamp(std::lround(v), 0L, 255L)); }

CloudPoint point_of(const Voxel& v) {
  CloudPoint p;
  p.x_m = v.x_m;
  p.y_m = v.y_m;
  p.z_m = v.z_m;
  p.r = to_u8(v.r);
  p.g = to_u8(v.g);
  p.b = to_u8(v.b);
  return p;
}

constexpr size_t kStreamBatch = 65'536;  // points per MapStreamSink call at most

}  // namespace

LocalMapper::LocalMapper(const LocalMapperConfig& config, const hal::PinholeIntrinsics& K, VoxelMap map,
                         JunctionAligner junction, FineRegionMap fine)
    : config_(config),
      K_(K),
      map_(std::move(map)),
      junction_(std::move(junction)),
      fine_(std::move(fine)),
      cloud_arena_(
          std::make_unique<core::Arena>(keyframe_cloud_capacity_bytes(K.width, K.height, config.cloud))) {
  for (auto& a : junction_arena_)
    a = std::make_unique<core::Arena>(
        keyframe_cloud_capacity_bytes(K.width, K.height, config.junction_cloud));
  segment_.keyframes.reserve(static_cast<size_t>(config.max_keyframes_per_segment));
  map_size_after_kf_.assign(static_cast<size_t>(config.stream_lag_keyframes) + 1, 0);
  stream_points_.resize(kStreamBatch);
  stream_ids_.resize(kStreamBatch);
}

LocalMapper::LocalMapper(LocalMapper&&) noexcept = default;
LocalMapper& LocalMapper::operator=(LocalMapper&&) noexcept = default;
LocalMapper::~LocalMapper() = default;

core::Expected<LocalMapper> LocalMapper::create(const LocalMapperConfig& config,
                                                const hal::PinholeIntrinsics& K, int max_features) {
  if (!K.valid()) return core::InvalidArgument("local mapper: invalid intrinsics");
  if (!(config.segment_max_travel_m > 0) || config.segment_max_points < 1 || config.keyframe_lag < 0 ||
      config.max_keyframes_per_segment < 2 || config.stream_lag_keyframes < 0 ||
      config.stream_min_points < 1) {
    return core::InvalidArgument(
        "local mapper: needs segment_max_travel_m > 0, segment_max_points >= 1, keyframe_lag >= 0, "
        "max_keyframes_per_segment >= 2, stream_lag_keyframes >= 0, stream_min_points >= 1");
  }
  if (config.segment_max_points > config.voxels.max_voxels) {
    return core::InvalidArgument(
        "local mapper: segment_max_points (" + std::to_string(config.segment_max_points) +
        ") exceeds the voxel map's capacity (" + std::to_string(config.voxels.max_voxels) + ")");
  }
  auto map = VoxelMap::create(config.voxels);
  if (!map.ok()) return map.status();
  // NDT's capacity: every sampled pixel of a junction cloud.
  JunctionConfig junction_config = config.junction;
  const int stride = std::max(1, config.junction_cloud.stride_px);
  const int samples = ((K.width + stride - 1) / stride) * ((K.height + stride - 1) / stride);
  junction_config.ndt.max_source_points = samples;
  junction_config.ndt.max_target_points = samples;
  auto junction = JunctionAligner::create(junction_config, max_features);
  if (!junction.ok()) return junction.status();
  // A disabled fine map still exists (add_weld_region keeps the regions) but with a token voxel table.
  FineRegionConfig fine_config = config.fine;
  if (!fine_config.enabled) fine_config.voxels.max_voxels = 1;
  auto fine = FineRegionMap::create(fine_config, K);
  if (!fine.ok()) return core::InvalidArgument("local mapper: " + fine.status().message());
  return LocalMapper(config, K, std::move(map.value()), std::move(junction.value()), std::move(fine.value()));
}

void LocalMapper::update(const estimation::KeyframeStore& keyframes, SegmentSink* sink, bool flush) {
  if (keyframes.empty()) return;
  const int newest = keyframes.newest_id();
  // Sensor tags now, while the keyframe's samples are in the rings (keyframe_sensor_tags.hpp).
  for (int id = std::max(tagged_upto_ + 1, keyframes.oldest_id()); id <= newest; ++id)
    if (const estimation::Keyframe* kf = keyframes.get(id)) sensor_tags_.remember(id, kf->t_ns);
  tagged_upto_ = std::max(tagged_upto_, newest);
  const int last = flush ? newest : newest - config_.keyframe_lag;
  // A keyframe that left the ring before it was fused keeps nothing to fuse; start at the oldest.
  next_id_ = std::max(next_id_, keyframes.oldest_id());
  for (; next_id_ <= last; ++next_id_) fuse(keyframes, next_id_, sink);
}

void LocalMapper::finish(const estimation::KeyframeStore& keyframes, SegmentSink* sink) {
  update(keyframes, sink, true);
  if (segment_open_) close_segment(sink);
}

void LocalMapper::fuse(const estimation::KeyframeStore& keyframes, int id, SegmentSink* sink) {
  const estimation::Keyframe* kf = keyframes.get(id);
  const Eigen::Isometry3d T_world_cam = keyframes.pose(id);
  const int64_t t_ns = kf != nullptr ? kf->t_ns : 0;
  const cv::Mat* bgr = keyframes.bgr(id);
  const cv::Mat* depth = keyframes.depth_m(id);
  const bool have_images = depth != nullptr && !depth->empty();

  // This keyframe's junction cloud (camera frame), kept until the next keyframe.
  const int cur = 1 - junction_prev_;
  junction_arena_[cur]->reset();
  KeyframeCloud junction_cloud;
  if (have_images) {
    auto c = build_keyframe_cloud(cv::Mat(), *depth, K_, Eigen::Isometry3d::Identity(),
                                  config_.junction_cloud, junction_arena_[cur].get());
    if (c.ok())
      junction_cloud = c.value();
    else
      ++counters_.cloud_errors;
  }

  JunctionRecord junction;
  if (segment_open_) {
    const double step_m = (T_world_cam.translation() - T_world_last_.translation()).norm();
    const bool cut = segment_.travelled_m + step_m >= config_.segment_max_travel_m ||
                     map_.size() >= config_.segment_max_points ||
                     static_cast<int>(segment_.keyframes.size()) >= config_.max_keyframes_per_segment;
    if (!cut) {
      segment_.travelled_m += step_m;
    } else {
      // Junction between the last keyframe before the cut (a) and this one (b).
      const estimation::Keyframe* a = keyframes.get(last_id_);
      const Eigen::Isometry3d T_a_b_odometry = T_world_last_.inverse() * T_world_cam;
      Eigen::Isometry3d T_a_b = T_a_b_odometry, T_a_b_measured = T_a_b_odometry;
      junction.keyframe_before = last_id_;
      junction.keyframe_after = id;
      if (a != nullptr && kf != nullptr) {
        const auto t0 = std::chrono::steady_clock::now();
        const JunctionResult r = junction_.align(*a, *kf, K_, view_of(junction_cloud_prev_),
                                                 view_of(junction_cloud), T_a_b_odometry);
        const double ms =
            std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
        HWR_LOG_INFO("map",
                     "junction %u: keyframes %d -> %d, orb %d/%d inliers (%s seed), ndt %s (%s, %d it, "
                     "%d + %d points), orb rms %.2f px (ndt %.2f px), odometry %s (chi2 %.1f), %.1f ms",
                     next_segment_id_, last_id_, id, r.orb_inliers, r.orb_matches,
                     r.seed == JunctionSeed::kOrb ? "orb" : "odometry", r.ndt_used ? "used" : "not used",
                     r.ndt.converged ? "converged" : ndt_failure_name(r.ndt.failure), r.ndt.iterations,
                     junction_cloud_prev_.size, junction_cloud.size, r.orb_rms_px, r.ndt_orb_rms_px,
                     r.fused ? "fused" : (r.odometry_kept ? "kept (ORB alone)" : "not fused"), r.fusion_chi2,
                     ms);
        T_a_b = r.T_a_b;
        T_a_b_measured = r.T_a_b_measured;
        junction.fused = r.fused;
        junction.ndt_used = r.ndt_used;
        junction.odometry_kept = r.odometry_kept;
        junction.valid = r.seed == JunctionSeed::kOrb || r.ndt_used;
        junction.orb_matches = r.orb_matches;
        junction.orb_inliers = r.orb_inliers;
        junction.ndt_converged = r.ndt.converged;
        junction.ndt_iterations = r.ndt.iterations;
        junction.ndt_fitness = r.ndt.fitness;
        counters_.junctions_orb += r.seed == JunctionSeed::kOrb ? 1 : 0;
        counters_.junctions_ndt += r.ndt_used ? 1 : 0;
      }
      const Eigen::Isometry3d T_prevseg_world = segment_.T_world_segment.inverse();
      junction.T_prev_segment_segment = T_prevseg_world * T_world_last_ * T_a_b;
      junction.T_prev_segment_segment_odometry = T_prevseg_world * T_world_cam;
      junction.T_prev_segment_segment_measured = T_prevseg_world * T_world_last_ * T_a_b_measured;
      close_segment(sink);
    }
  }
  if (!segment_open_) {
    segment_.segment_id = next_segment_id_++;
    segment_.T_world_segment = T_world_cam;
    segment_.junction = junction;
    segment_.travelled_m = 0;
    segment_.t_first_ns = t_ns;
    segment_.keyframes.clear();
    segment_.points_segment.clear();
    map_.clear();
    segment_open_ = true;
  }
  segment_.t_last_ns = t_ns;

  fine_.settle(id, T_world_cam);  // regions detected on this keyframe: its settled pose
  if (have_images) {
    cloud_arena_->reset();
    const Eigen::Isometry3d T_segment_cam = segment_.T_world_segment.inverse() * T_world_cam;
    auto c = build_keyframe_cloud(bgr != nullptr ? *bgr : cv::Mat(), *depth, K_, T_segment_cam, config_.cloud,
                                  cloud_arena_.get());
    if (c.ok())
      map_.insert(c.value());
    else
      ++counters_.cloud_errors;
    fine_.insert_keyframe(bgr != nullptr ? *bgr : cv::Mat(), *depth, T_world_cam, segment_.T_world_segment);
  } else {
    ++counters_.keyframes_without_images;
  }
  segment_.keyframes.push_back(stored_keyframe(kf, id, T_world_cam, t_ns));
  sensor_tags_.tag(&segment_.keyframes.back());
  ++counters_.keyframes_fused;

  if (stream_sink_ != nullptr) {
    // Voxels made at least stream_lag_keyframes keyframes ago are ready.
    const size_t ring = map_size_after_kf_.size();
    map_size_after_kf_[static_cast<size_t>(keyframes_in_segment_) % ring] = map_.size();
    ++keyframes_in_segment_;
    if (keyframes_in_segment_ >= static_cast<int>(ring)) {
      const int ready = map_size_after_kf_[static_cast<size_t>(keyframes_in_segment_) % ring];
      if (ready - streamed_voxels_ >= config_.stream_min_points) stream_voxels(ready, false);
    }
  }

  junction_prev_ = cur;
  junction_cloud_prev_ = junction_cloud;
  last_id_ = id;
  T_world_last_ = T_world_cam;
}

void LocalMapper::stream_voxels(int upto, bool segment_complete) {
  do {
    const int n = std::min(upto - streamed_voxels_, static_cast<int>(kStreamBatch));
    for (int i = 0; i < n; ++i) {
      const uint32_t slot = map_.created(streamed_voxels_ + i);
      stream_points_[static_cast<size_t>(i)] = point_of(map_.at_slot(slot));
      stream_ids_[static_cast<size_t>(i)] = slot;
    }
    streamed_voxels_ += n;
    stream_sink_->stream(segment_.segment_id, segment_.T_world_segment, stream_points_.data(),
                         stream_ids_.data(), n, segment_complete && streamed_voxels_ == upto);
  } while (streamed_voxels_ < upto);
}

void LocalMapper::close_segment(SegmentSink* sink) {
  if (stream_sink_ != nullptr) stream_voxels(map_.size(), true);
  streamed_voxels_ = 0;
  keyframes_in_segment_ = 0;
  segment_.points_segment.clear();
  segment_.points_segment.reserve(static_cast<size_t>(map_.size()));
  map_.for_each([&](const Voxel& v) { segment_.points_segment.push_back(point_of(v)); });
  counters_.points_closed += segment_.points_segment.size();
  fine_.take_segment(segment_.T_world_segment, &segment_.fine_points_segment, &segment_.fine_counts,
                     &segment_.weld_regions);
  segment_.fine_voxel_m = segment_.fine_points_segment.empty() ? 0.0 : config_.fine.voxels.voxel_m;
  counters_.fine_points_closed += segment_.fine_points_segment.size();
  ++counters_.segments_closed;
  if (sink != nullptr) sink->take(std::move(segment_));
  segment_ = SegmentRecord();
  segment_.keyframes.reserve(static_cast<size_t>(config_.max_keyframes_per_segment));
  map_.clear();
  segment_open_ = false;
}

}  // namespace hwr::recon
