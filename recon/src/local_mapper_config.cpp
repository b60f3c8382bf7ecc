#include "hwr/recon/local_mapper_config.hpp"

#include <vector>

namespace hwr::recon {

void read_local_mapper_config(core::ConfigMap map, LocalMapperConfig* c) {
  map.get("voxel_m", &c->voxels.voxel_m)
      .get("max_voxels", &c->voxels.max_voxels)
      .get("segment_max_travel_m", &c->segment_max_travel_m)
      .get("segment_max_points", &c->segment_max_points)
      .get("keyframe_lag", &c->keyframe_lag)
      .get("stream_lag_keyframes", &c->stream_lag_keyframes)
      .get("stream_min_points", &c->stream_min_points);
  core::ConfigMap cloud = map.child("cloud");
  cloud.get("min_depth_m", &c->cloud.min_depth_m)
      .get("max_depth_m", &c->cloud.max_depth_m)
      .get("stride_px", &c->cloud.stride_px)
      .get("max_depth_step", &c->cloud.max_depth_step);
  core::ConfigMap junction = map.child("junction");
  std::vector<double> resolutions;
  junction.get("min_orb_inliers", &c->junction.min_orb_inliers)
      .get("cloud_stride_px", &c->junction_cloud.stride_px)
      .get("ndt_resolutions_m", &resolutions)
      .get("ndt_outlier_ratio", &c->junction.ndt.outlier_ratio)
      .get("ndt_max_iterations", &c->junction.ndt.max_iterations)
      .get("max_ndt_correction_m", &c->junction.max_ndt_correction_m)
      .get("max_ndt_correction_rad", &c->junction.max_ndt_correction_rad)
      .get("fuse_odometry", &c->junction.fuse_odometry)
      .get("odometry_sigma_rad", &c->junction.odometry_sigma_rad)
      .get("odometry_sigma_m", &c->junction.odometry_sigma_m)
      .get("orb_covariance_scale", &c->junction.orb_covariance_scale)
      .get("fusion_gate_chi2", &c->junction.fusion_gate_chi2)
      .get("fuse_orb_alone", &c->junction.fuse_orb_alone);
  core::ConfigMap fine = map.child("fine");
  fine.get("enabled", &c->fine.enabled)
      .get("voxel_m", &c->fine.voxels.voxel_m)
      .get("max_voxels", &c->fine.voxels.max_voxels)
      .get("min_depth_m", &c->fine.cloud.min_depth_m)
      .get("max_depth_m", &c->fine.cloud.max_depth_m)
      .get("stride_px", &c->fine.cloud.stride_px)
      .get("max_depth_step", &c->fine.cloud.max_depth_step)
      .get("edge_keeps_nearer", &c->fine.cloud.edge_keeps_nearer)
      .get("max_regions", &c->fine.max_regions);
  if (junction.has("ndt_resolutions_m")) {
    if (resolutions.empty() || resolutions.size() > c->junction.ndt.resolutions_m.size()) {
      junction.record_error("ndt_resolutions_m", "expected 1 to 4 voxel sides, coarse to fine");
    } else {
      c->junction.ndt.resolutions_m.fill(0.0);
      for (size_t i = 0; i < resolutions.size(); ++i) c->junction.ndt.resolutions_m[i] = resolutions[i];
    }
  }
}

}  // namespace hwr::recon
