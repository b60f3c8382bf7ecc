#include "rgbd_odometry_peer.hpp"

#include <chrono>
#include <ctime>
#include <cmath>
#include <limits>
#include <utility>

#include <opencv2/core.hpp>

#include "hwr/hal/rgbd_frame.hpp"

#if HWR_HAVE_OPENCV_RGBD
#include <opencv2/imgproc.hpp>
#include <opencv2/rgbd.hpp>
#endif

namespace hwr::bench {

RgbdOdometryOptions rgbd_odometry_options_for(const hal::SourceInfo& info) {
  RgbdOdometryOptions o;
  if (info.name.rfind("tum:", 0) != 0) {
    o.min_depth_m = 0.2;
    o.max_depth_m = 10.0;
  }
  return o;
}

bool rgbd_odometry_available() {
#if HWR_HAVE_OPENCV_RGBD
  return true;
#else
  return false;
#endif
}

core::Expected<PeerRun> run_rgbd_odometry(const hal::ReplayLog& log, size_t max_frames) {
  RgbdOdometryOptions options = rgbd_odometry_options_for(log.info);
  options.max_frames = max_frames;
  return run_rgbd_odometry(log, options);
}

#if HWR_HAVE_OPENCV_RGBD

namespace {

cv::Mat camera_matrix(const hal::PinholeIntrinsics& k) {
  cv::Mat K = cv::Mat::eye(3, 3, CV_64FC1);
  K.at<double>(0, 0) = k.fx;
  K.at<double>(1, 1) = k.fy;
  K.at<double>(0, 2) = k.cx;
  K.at<double>(1, 2) = k.cy;
  return K;
}

Eigen::Isometry3d to_isometry(const cv::Mat& Rt) {
  Eigen::Matrix4d m;
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) m(r, c) = Rt.at<double>(r, c);
  }
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = m.topLeftCorner<3, 3>();
  T.translation() = m.topRightCorner<3, 1>();
  return T;
}

double process_cpu_ms() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return 1e3 * static_cast<double>(ts.tv_sec) + 1e-6 * static_cast<double>(ts.tv_nsec);
}

}  // namespace

core::Expected<PeerRun> run_rgbd_odometry(const hal::ReplayLog& log, const RgbdOdometryOptions& options) {
  if (!log.load_frame) return core::InvalidArgument(log.info.name + ": the log has no frame loader");
  if (!(options.max_depth_m > options.min_depth_m)) {
    return core::InvalidArgument("RgbdOdometry: max depth must exceed min depth");
  }
  const size_t n =
      options.max_frames > 0 ? std::min(options.max_frames, log.frame_t_ns.size()) : log.frame_t_ns.size();
  PeerRun run;
  run.name = "RgbdOdometry";
  run.T_world_cam.reserve(n);
  run.frame_ms.reserve(n);
  run.frame_cpu_ms.reserve(n);

  cv::Ptr<cv::rgbd::RgbdOdometry> odometry;
  // As in OpenCV's samples/odometry_evaluation.cpp: the frame just registered (src, with its
  // pyramids cached) becomes the next call's dst; the old dst is released and refilled.
  cv::Ptr<cv::rgbd::OdometryFrame> prev = cv::rgbd::OdometryFrame::create();
  cv::Ptr<cv::rgbd::OdometryFrame> curr = cv::rgbd::OdometryFrame::create();
  bool have_prev = false;
  Eigen::Isometry3d T_world_prev = Eigen::Isometry3d::Identity();
  hal::RgbdFrame frame;
  for (size_t i = 0; i < n; ++i) {
    const core::Status st = log.load_frame(i, &frame);
    if (!st.ok() || frame.bgr.empty() || frame.depth_m.type() != CV_32FC1) {
      ++run.failures;  // skipped: the next frame registers to the last good one
      continue;
    }
    if (!odometry) {
      odometry = cv::rgbd::RgbdOdometry::create(camera_matrix(frame.intrinsics),
                                                static_cast<float>(options.min_depth_m),
                                                static_cast<float>(options.max_depth_m));
    }
    // Fresh buffers each frame: the odometry frames keep references to them.
    cv::Mat gray, depth;
    cv::cvtColor(frame.bgr, gray, cv::COLOR_BGR2GRAY);
    frame.depth_m.copyTo(depth);
    depth.setTo(std::numeric_limits<float>::quiet_NaN(), depth == 0.0f);
    curr->image = gray;
    curr->depth = depth;

    Eigen::Isometry3d T_world_cur = T_world_prev;
    if (have_prev) {
      cv::Mat Rt;
      bool ok = false;
      const double c0 = process_cpu_ms();
      const auto t0 = std::chrono::steady_clock::now();
      try {
        ok = odometry->compute(curr, prev, Rt);
      } catch (const cv::Exception&) {
        ok = false;  // OpenCV asserts on degenerate input; a failed registration like any other
      }
      const auto t1 = std::chrono::steady_clock::now();
      run.frame_cpu_ms.push_back(process_cpu_ms() - c0);
      run.frame_ms.push_back(std::chrono::duration<double, std::milli>(t1 - t0).count());
      if (ok && Rt.rows == 4 && Rt.cols == 4 && Rt.type() == CV_64FC1) {
        T_world_cur = T_world_prev * to_isometry(Rt);  // Rt = T_prev_cur
      } else {
        ++run.failures;
      }
    }
    run.T_world_cam.push_back({log.frame_t_ns[i], T_world_cur});
    T_world_prev = T_world_cur;
    have_prev = true;
    prev->release();
    std::swap(prev, curr);
  }
  return run;
}

#else

core::Expected<PeerRun> run_rgbd_odometry(const hal::ReplayLog&, const RgbdOdometryOptions&) {
  return core::Unavailable(
      "RgbdOdometry peer unavailable: this build has no OpenCV contrib rgbd module (install "
      "libopencv-contrib-dev, toolchain/install-deps.sh --with-bench-peers, and reconfigure)");
}

#endif

}  // namespace hwr::bench
