#if HWR_WITH_SIM
#include "reloc_bench_run.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>

#include <opencv2/imgproc.hpp>

#include "hwr/sim/scenario.hpp"
#include "hwr/sim/world_frame.hpp"

namespace hwr::bench {
namespace {

recon::KeyframeCloudConfig query_cloud_config() {
  recon::KeyframeCloudConfig c;
  c.stride_px = 4;  // the query's local map: every 4th pixel (as tests/recon/test_relocalizer.cpp)
  return c;
}

estimation::OrbConfig orb_config(int max_features) {
  estimation::OrbConfig c;
  c.max_features = max_features;
  return c;
}

}  // namespace

RelocSimRun::RelocSimRun(sim::SimLiveLog live, int max_features)
    : live_(std::move(live)),
      orb_(orb_config(max_features), live_.log.info.intrinsics.width, live_.log.info.intrinsics.height),
      cloud_config_(query_cloud_config()),
      arena_(recon::keyframe_cloud_capacity_bytes(live_.log.info.intrinsics.width,
                                                  live_.log.info.intrinsics.height, cloud_config_)) {
  const hal::PinholeIntrinsics& K = live_.log.info.intrinsics;
  frame_.bgr.create(K.height, K.width, CV_8UC3);
  frame_.depth_m.create(K.height, K.width, CV_32FC1);
  const auto& gt = live_.groundtruth_T_world_cam_at_frames;
  path_m_.resize(gt.size(), 0.0);
  for (size_t i = 1; i < gt.size(); ++i) {
    path_m_[i] =
        path_m_[i - 1] + (gt[i].T_world_body.translation() - gt[i - 1].T_world_body.translation()).norm();
  }
}

core::Expected<std::unique_ptr<RelocSimRun>> RelocSimRun::open(const std::string& scenario,
                                                               int max_features) {
  auto spec = sim::load_scenario(scenario);
  if (!spec.ok()) return spec.status();
  auto live = sim::open_sim_live_log(spec.value(), 0.0);
  if (!live.ok()) return live.status();
  if (live->groundtruth_T_world_cam_at_frames.size() != live->log.frame_t_ns.size()) {
    return core::Internal("reloc bench: " + scenario + ": ground truth and frames differ in count");
  }
  return std::unique_ptr<RelocSimRun>(new RelocSimRun(std::move(live).value(), max_features));
}

Eigen::Isometry3d RelocSimRun::T_run_imu_at(int64_t t_ns) const {
  const auto& gt = live_.groundtruth_T_world_cam;
  auto it = std::lower_bound(gt.begin(), gt.end(), t_ns,
                             [](const core::StampedPose& p, int64_t t) { return p.t_ns < t; });
  if (it == gt.end()) it = gt.end() - 1;
  if (it != gt.begin() && (t_ns - (it - 1)->t_ns) < (it->t_ns - t_ns)) --it;
  return it->T_world_body * live_.calibration.T_imu_cam.inverse();
}

core::Status RelocSimRun::render(size_t i, RelocKeyframe* out) {
  const auto t0 = std::chrono::steady_clock::now();
  if (i >= frames()) return core::OutOfRange("reloc bench: frame " + std::to_string(i) + " beyond the run");
  HWR_RETURN_IF_ERROR(live_.log.load_frame(i, &frame_));
  out->frame = i;
  out->t_ns = live_.log.frame_t_ns[i];
  out->T_run_cam = live_.groundtruth_T_world_cam_at_frames[i].T_world_body;
  cv::cvtColor(frame_.bgr, gray_, cv::COLOR_BGR2GRAY);
  HWR_RETURN_IF_ERROR(orb_.extract(gray_, frame_.depth_m, K(), &out->features));
  arena_.reset();
  auto cloud = recon::build_keyframe_cloud(frame_.bgr, frame_.depth_m, K(), Eigen::Isometry3d::Identity(),
                                           cloud_config_, &arena_);
  if (!cloud.ok()) return cloud.status();
  out->cloud_cam.assign(cloud->points, cloud->points + cloud->size);
  render_s_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  ++renders_;
  return core::Status::Ok();
}

RelocStart::RelocStart(RelocSimRun* run, size_t first_frame, size_t keyframe_step, int max_features)
    : run_(run),
      first_frame_(first_frame),
      step_(std::max<size_t>(keyframe_step, 1)),
      next_frame_(first_frame),
      max_features_(max_features),
      t_first_ns_(run->live().log.frame_t_ns[first_frame]) {
  // The robot switched on at this frame: its world is the gravity-aligned first IMU frame.
  const Eigen::Isometry3d T_scene_run = run->live().calibration.T_scene_world;
  const Eigen::Isometry3d T_scene_imu0 = T_scene_run * run->T_run_imu_at(t_first_ns_);
  T_start_run_ = sim::world_frame_from_first_imu_pose(T_scene_imu0).inverse() * T_scene_run;
  auto v = recon::VoxelMap::create({0.05, 1'000'000});
  if (v.ok()) voxels_ = std::make_unique<recon::VoxelMap>(std::move(v).value());
}

Eigen::Isometry3d RelocStart::T_scene_start() const {
  return run_->live().calibration.T_scene_world * T_start_run_.inverse();
}

core::Expected<int> RelocStart::keyframe_at_motion(double moved_m) {
  for (size_t k = 0; k < keyframes_.size(); ++k) {
    if (moved_m_[k] >= moved_m) return static_cast<int>(k);
  }
  const hal::PinholeIntrinsics& K = run_->K();
  while (next_frame_ < run_->frames()) {
    const size_t i = next_frame_;
    next_frame_ += step_;
    const Eigen::Isometry3d& T = run_->live().groundtruth_T_world_cam_at_frames[i].T_world_body;
    double moved = 0;
    if (!keyframes_.empty()) {
      // The robot makes keyframes on motion: standing still (< 5 cm, < 3 deg) gives none.
      const Eigen::Isometry3d& last = keyframes_.back()->T_run_cam;
      const double step_m = (T.translation() - last.translation()).norm();
      const double step_rad = Eigen::AngleAxisd(last.linear().transpose() * T.linear()).angle();
      if (step_m < 0.05 && step_rad < 3.0 * M_PI / 180.0) continue;
      moved = moved_m_.back() + step_m;
    }
    auto kf = std::make_unique<RelocKeyframe>(max_features_, K.width, K.height);
    HWR_RETURN_IF_ERROR(run_->render(i, kf.get()));
    keyframes_.push_back(std::move(kf));
    moved_m_.push_back(moved);
    if (moved >= moved_m) return static_cast<int>(keyframes_.size() - 1);
  }
  return -1;
}

void RelocStart::local_map(int k, const Eigen::Vector3d& p_world_cam,
                           const recon::RelocalizationWorkerConfig& worker,
                           std::vector<recon::CloudPoint>* out) {
  out->clear();
  if (!voxels_) return;
  if (k < voxels_upto_) {
    voxels_->clear();
    voxels_upto_ = -1;
  }
  std::vector<recon::CloudPoint> moved;
  for (int j = voxels_upto_ + 1; j <= k; ++j) {
    const Eigen::Isometry3d T = T_start_cam(j);
    const RelocKeyframe& kf = keyframe(j);
    moved.resize(kf.cloud_cam.size());
    for (size_t p = 0; p < kf.cloud_cam.size(); ++p) {
      const recon::CloudPoint& c = kf.cloud_cam[p];
      const Eigen::Vector3d q = T * Eigen::Vector3d(c.x_m, c.y_m, c.z_m);
      moved[p] = c;
      moved[p].x_m = static_cast<float>(q.x());
      moved[p].y_m = static_cast<float>(q.y());
      moved[p].z_m = static_cast<float>(q.z());
    }
    voxels_->insert(moved.data(), static_cast<int>(moved.size()));
  }
  voxels_upto_ = std::max(voxels_upto_, k);
  out->resize(static_cast<size_t>(worker.max_local_points));
  const int n = recon::gather_local_map(*voxels_, Eigen::Isometry3d::Identity(), p_world_cam,
                                        worker.local_radius_m, out->data(), worker.max_local_points);
  out->resize(static_cast<size_t>(n));
}

void RelocStart::feed(int64_t t_ns, const Eigen::Vector3d& antenna_imu_m, recon::CurrentSensorPriors* priors,
                      int64_t* fed_until_ns) const {
  const int64_t from = std::max(*fed_until_ns, t_first_ns_ - 1);
  const hal::ReplayLog& log = run_->live().log;
  for (const hal::MagSample& m : log.mag) {
    if (m.t_ns <= from || m.t_ns > t_ns) continue;
    priors->add_mag(m, (T_start_run_ * run_->T_run_imu_at(m.t_ns)).linear());
  }
  for (const hal::GnssFix& g : log.gnss) {
    if (g.t_ns <= from || g.t_ns > t_ns || !g.has_3d_fix()) continue;
    priors->add_gnss(g, T_start_run_ * run_->T_run_imu_at(g.t_ns) * antenna_imu_m);
  }
  *fed_until_ns = std::max(*fed_until_ns, t_ns);
}

}  // namespace hwr::bench
#endif  // HWR_WITH_SIM
