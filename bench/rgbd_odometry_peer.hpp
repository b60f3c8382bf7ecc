#pragma once
// Peer for the pose-estimation benches (issue #3 speed acceptance): OpenCV-contrib's
// cv::rgbd::RgbdOdometry, the dense photometric + depth frame-to-frame odometry of Steinbrücker,
// Sturm and Cremers ("Real-Time Visual Odometry from Dense RGB-D Images", ICCV 2011 workshops),
// run over every frame of a replay log in order, without the scheduler, the way OpenCV's own
// samples/odometry_evaluation.cpp runs it. Bench-only: built when bench/CMakeLists.txt finds
// opencv_rgbd (HWR_HAVE_OPENCV_RGBD=1); otherwise run_rgbd_odometry() says it is unavailable.

#include <cstddef>
#include <string>
#include <vector>

#include "hwr/core/status.hpp"
#include "hwr/core/tum_trajectory.hpp"
#include "hwr/hal/replay_source.hpp"

namespace hwr::bench {

struct PeerRun {
  std::vector<core::StampedPose> T_world_cam;  // one per loaded frame; the first frame is the world
  std::vector<double> frame_ms;                // time of each odometry call (frames 1..n-1), ms
  // Process CPU time of each call, ms (all OpenCV worker threads; on a shared machine this is
  // steadier than frame_ms, which also counts other processes' slices).
  std::vector<double> frame_cpu_ms;
  int failures = 0;  // odometry calls that failed (pose kept) + frames that could not be loaded
  std::string name;  // "RgbdOdometry"
};

struct RgbdOdometryOptions {
  // Pixels outside (min, max) depth are not used. OpenCV's defaults (0, 4 m) suit the Kinect of
  // the TUM sequences; the simulator and stereo sources see further.
  double min_depth_m = 0.0;
  double max_depth_m = 4.0;
  size_t max_frames = 0;  // 0: every frame
};

// OpenCV's defaults for TUM ("tum:" sources), a 0.2-10 m range for the others (simulator runs
// render the ZED 2i's range, stereo depth is noisy far away).
RgbdOdometryOptions rgbd_odometry_options_for(const hal::SourceInfo& info);

// True when this build has the OpenCV rgbd module.
bool rgbd_odometry_available();

// Runs cv::rgbd::RgbdOdometry (default parameters except the camera matrix, from the first frame's
// intrinsics, and the depth range) frame to frame over the log: frame i is loaded with
// log.load_frame(i, ...), converted to 8-bit gray and to float depth in metres with invalid pixels
// as NaN (what OpenCV's samples and tests feed it: NaN keeps the depth pyramid from averaging
// holes into valid depth), and registered to frame i-1. compute(src = frame i, dst = frame i-1)
// returns Rt with p_dst = Rt · p_src, i.e. T_prev_cur, so T_world_cur = T_world_prev · T_prev_cur.
// Only the compute() call is timed (steady_clock, and process CPU time); it includes building the
// new frame's pyramids.
// A failed call keeps the previous pose and is counted. The log's loader is used from this thread,
// in index order; pass a log nobody else is replaying.
core::Expected<PeerRun> run_rgbd_odometry(const hal::ReplayLog& log, const RgbdOdometryOptions& options);
core::Expected<PeerRun> run_rgbd_odometry(const hal::ReplayLog& log, size_t max_frames = 0);

}  // namespace hwr::bench
