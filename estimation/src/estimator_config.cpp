#include "hwr/estimation/estimator_config.hpp"

namespace hwr::estimation {

void read_estimator_config(core::ConfigMap map, PoseEstimatorConfig* c) {
  map.get("use_imu", &c->use_imu)
      .get("full_ba_at_end", &c->full_ba_at_end)
      .get("static_init_timeout_s", &c->static_init_timeout_s)
      .get("visual_cov_inflation", &c->visual_cov_inflation)
      .get("depth_sigma_per_m2", &c->depth_sigma_per_m2);

  core::ConfigMap orb = map.child("orb");
  orb.get("max_features", &c->tracker.orb.max_features)
      .get("scale_factor", &c->tracker.orb.scale_factor)
      .get("levels", &c->tracker.orb.levels)
      .get("fast_threshold", &c->tracker.orb.fast_threshold)
      .get("min_fast_threshold", &c->tracker.orb.min_fast_threshold)
      .get("max_fast_threshold", &c->tracker.orb.max_fast_threshold)
      .get("corners_per_feature", &c->tracker.orb.corners_per_feature)
      .get("grid_cell_px", &c->tracker.orb.grid_cell_px)
      .get("min_depth_m", &c->tracker.orb.min_depth_m)
      .get("max_depth_m", &c->tracker.orb.max_depth_m);

  core::ConfigMap kf = map.child("keyframes");
  kf.get("translation_m", &c->tracker.keyframe_translation_m)
      .get("rotation_rad", &c->tracker.keyframe_rotation_rad)
      .get("inlier_fraction", &c->tracker.keyframe_inlier_fraction)
      .get("ring_capacity", &c->tracker.keyframes.capacity)
      .get("image_slots", &c->tracker.keyframes.image_slots);

  core::ConfigMap tr = map.child("tracking");
  tr.get("map_point_capacity", &c->tracker.map_point_capacity)
      .get("local_map_keyframes", &c->tracker.local_map_keyframes)
      .get("max_local_points", &c->tracker.max_local_points)
      .get("match_radius_px", &c->tracker.match.radius_px)
      .get("match_max_hamming", &c->tracker.match.max_distance)
      .get("min_matches", &c->tracker.min_matches)
      .get("min_inliers", &c->tracker.min_inliers)
      .get("recovery_keyframes", &c->tracker.recovery_keyframes);

  core::ConfigMap ba = map.child("local_ba");
  ba.get("enabled", &c->local_ba_enabled)
      .get("window_keyframes", &c->local_ba.window_keyframes)
      .get("fixed_keyframes", &c->local_ba.fixed_keyframes)
      .get("max_iterations", &c->local_ba.options.max_iterations)
      .get("huber_px", &c->local_ba.options.huber_px)
      .get("use_depth", &c->local_ba.options.use_depth);

  core::ConfigMap imu = map.child("imu");
  imu.get("gyro_noise_density", &c->imu_noise.gyro_noise_density)
      .get("accel_noise_density", &c->imu_noise.accel_noise_density)
      .get("gyro_random_walk", &c->imu_noise.gyro_random_walk)
      .get("accel_random_walk", &c->imu_noise.accel_random_walk)
      .get("static_window_s", &c->static_init.window_s);

  if (c->tracker.keyframe_translation_m <= 0) kf.record_error("translation_m", "must be > 0");
  if (c->tracker.keyframe_rotation_rad <= 0) kf.record_error("rotation_rad", "must be > 0");
  if (c->tracker.orb.max_features < 50) orb.record_error("max_features", "must be >= 50");
  if (c->tracker.orb.levels < 1 || c->tracker.orb.levels > 16)
    orb.record_error("levels", "must be in [1, 16]");
  if (!(c->tracker.orb.scale_factor > 1.0f)) orb.record_error("scale_factor", "must be > 1");
  if (c->tracker.orb.max_fast_threshold < c->tracker.orb.fast_threshold)
    orb.record_error("max_fast_threshold", "must be >= fast_threshold");
  if (!(c->tracker.orb.corners_per_feature >= 0.0f))
    orb.record_error("corners_per_feature", "must be >= 0 (0: fixed threshold)");
  if (c->tracker.map_point_capacity < 1000) tr.record_error("map_point_capacity", "must be >= 1000");
  if (c->tracker.max_local_points < 100) tr.record_error("max_local_points", "must be >= 100");
  if (c->tracker.local_map_keyframes < 1) tr.record_error("local_map_keyframes", "must be >= 1");
  if (c->tracker.recovery_keyframes < 1) tr.record_error("recovery_keyframes", "must be >= 1");
  if (c->tracker.min_inliers < 6 || c->tracker.min_inliers > c->tracker.min_matches) {
    tr.record_error("min_inliers", "must be in [6, min_matches]");
  }
  if (!(c->depth_sigma_per_m2 > 0)) map.record_error("depth_sigma_per_m2", "must be > 0");
  if (c->local_ba.window_keyframes < 2) ba.record_error("window_keyframes", "must be >= 2");
  if (c->tracker.keyframes.capacity < c->local_ba.window_keyframes + c->local_ba.fixed_keyframes) {
    kf.record_error("ring_capacity", "must hold the bundle-adjustment window and its fixed keyframes");
  }
}

core::Expected<PoseEstimatorConfig> load_estimator_config(const std::string& path) {
  auto doc = core::ConfigDocument::load_file(path);
  if (!doc.ok()) return doc.status();
  PoseEstimatorConfig config;
  read_estimator_config(doc->root().child("estimation"), &config);
  HWR_RETURN_IF_ERROR(doc->finish());
  return config;
}

}  // namespace hwr::estimation
