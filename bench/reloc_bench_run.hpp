#pragma once
// `hwr-bench reloc` (issue #6, paper Table IV): the current run of a relocalization start. A simulator
// run (the revisit scenario) is opened live; a start at frame f0 is a robot switched on there: its
// world frame is the gravity-aligned frame of its first IMU pose (hal/sim world_frame.hpp), its
// keyframes are the run's frames from f0 on (every keyframe_step-th frame, skipped while standing
// still), rendered with ORB features and a keyframe cloud, posed by the simulator's ground truth (the
// current run's relative poses over these few metres come from the simulator, not from the tracker),
// and its magnetometer samples and GNSS fixes are the run's streams from f0's time on, with the true
// attitude and antenna position.

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <opencv2/core.hpp>

#include "hwr/core/arena.hpp"
#include "hwr/core/status.hpp"
#include "hwr/estimation/frame_features.hpp"
#include "hwr/estimation/orb_extractor.hpp"
#include "hwr/hal/rgbd_frame.hpp"
#include "hwr/recon/keyframe_cloud.hpp"
#include "hwr/recon/relocalization_priors.hpp"
#include "hwr/recon/relocalization_worker.hpp"
#include "hwr/recon/voxel_map.hpp"
#include "hwr/sim/sim_live_log.hpp"

namespace hwr::bench {

struct RelocKeyframe {
  RelocKeyframe(int capacity, int w, int h) : features(capacity, w, h) {}
  size_t frame = 0;
  int64_t t_ns = 0;
  Eigen::Isometry3d T_run_cam = Eigen::Isometry3d::Identity();  // the simulated run's world frame (truth)
  estimation::FrameFeatures features;
  std::vector<recon::CloudPoint> cloud_cam;  // every 4th pixel, camera frame
};

// A simulated run opened live, with its truth, its path length per frame and a keyframe renderer.
class RelocSimRun {
 public:
  static core::Expected<std::unique_ptr<RelocSimRun>> open(const std::string& scenario, int max_features);

  const sim::SimLiveLog& live() const { return live_; }
  const hal::PinholeIntrinsics& K() const { return live_.log.info.intrinsics; }
  const Eigen::Isometry3d& T_imu_cam() const { return live_.calibration.T_imu_cam; }
  size_t frames() const { return live_.log.frame_t_ns.size(); }
  double path_at_frame_m(size_t i) const { return path_m_[i]; }
  // T_run_imu at time t_ns (nearest ground-truth sample, IMU rate).
  Eigen::Isometry3d T_run_imu_at(int64_t t_ns) const;
  // Renders frame i into a keyframe (ORB features, cloud). Not thread-safe.
  core::Status render(size_t i, RelocKeyframe* out);
  double render_s() const { return render_s_; }
  int renders() const { return renders_; }

 private:
  RelocSimRun(sim::SimLiveLog live, int max_features);
  sim::SimLiveLog live_;
  std::vector<double> path_m_;
  estimation::GridOrbExtractor orb_;
  recon::KeyframeCloudConfig cloud_config_;
  core::Arena arena_;
  hal::RgbdFrame frame_;
  cv::Mat gray_;
  double render_s_ = 0;
  int renders_ = 0;
};

// One start: the keyframes rendered so far (extended on demand), in the start's own world frame.
class RelocStart {
 public:
  RelocStart(RelocSimRun* run, size_t first_frame, size_t keyframe_step, int max_features);

  size_t first_frame() const { return first_frame_; }
  int64_t t_first_ns() const { return t_first_ns_; }
  // T_start_run: the run's world frame in this start's world frame.
  const Eigen::Isometry3d& T_start_run() const { return T_start_run_; }
  // The run's world frame in the scene (truth), and this start's.
  Eigen::Isometry3d T_scene_start() const;

  // Renders keyframes until the path moved since the start reaches moved_m (or the run ends).
  // Returns the index of the keyframe at which it did, or -1 at the end of the run.
  core::Expected<int> keyframe_at_motion(double moved_m);
  const RelocKeyframe& keyframe(int k) const { return *keyframes_[static_cast<size_t>(k)]; }
  double moved_at(int k) const { return moved_m_[static_cast<size_t>(k)]; }
  Eigen::Isometry3d T_start_cam(int k) const { return T_start_run_ * keyframe(k).T_run_cam; }
  // The local map of keyframes 0..k (5 cm voxels, start frame), as RelocalizationWorker sends it
  // (recon::gather_local_map with `worker`'s radius and cap about p_world_cam), into *out.
  void local_map(int k, const Eigen::Vector3d& p_world_cam, const recon::RelocalizationWorkerConfig& worker,
                 std::vector<recon::CloudPoint>* out);
  // Feeds the run's magnetometer samples and 3D GNSS fixes with t in (fed_until, t_ns] to *priors,
  // with the true attitude / antenna position in the start frame. fed_until_ns tracks progress.
  void feed(int64_t t_ns, const Eigen::Vector3d& antenna_imu_m, recon::CurrentSensorPriors* priors,
            int64_t* fed_until_ns) const;

 private:
  RelocSimRun* run_;
  size_t first_frame_, step_, next_frame_;
  int max_features_;
  int64_t t_first_ns_;
  Eigen::Isometry3d T_start_run_;
  std::vector<std::unique_ptr<RelocKeyframe>> keyframes_;
  std::vector<double> moved_m_;
  std::unique_ptr<recon::VoxelMap> voxels_;
  int voxels_upto_ = -1;
};

}  // namespace hwr::bench
