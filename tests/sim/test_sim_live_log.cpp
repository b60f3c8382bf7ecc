// The live simulator source renders the run hwr-sim would write: every frame equals the written
// one (colour and right image exactly, depth up to the 16-bit quantisation, the same invalid
// pixels), every sample and ground-truth pose equals the written files', the log replays through
// hal::ReplaySource to the end, and a bad scenario fails with hwr-sim's own error.
// Oracle throughout: write_run's files for the same scenario, read back with the project's readers.

#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <gtest/gtest.h>

#include "hwr/core/file_io.hpp"
#include "hwr/core/tum_trajectory.hpp"
#include "hwr/hal/replay_source.hpp"
#include "hwr/hal/sensor_streams.hpp"
#include "hwr/sim/run_writer.hpp"
#include "hwr/sim/scenario.hpp"
#include "hwr/sim/sim_calibration.hpp"
#include "hwr/sim/sim_live_log.hpp"
#include "hwr/sim/sim_run_replay.hpp"

namespace hwr::sim {
namespace {

namespace fs = std::filesystem;

// The whole file (empty when it cannot be read: the comparisons then fail and say so).
std::string slurp(const fs::path& p) {
  std::string text;
  if (!core::read_file(p.string(), &text).ok()) text.clear();
  return text;
}

// A scratch folder per test and process (ctest runs tests in parallel processes).
fs::path scratch(const std::string& what) {
  const fs::path dir = fs::path(HWR_BINARY_DIR) / ("sim_live_" + what + "_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  return dir;
}

// Files named in a TUM list, in order ("timestamp filename" lines after '#' comments).
std::vector<std::string> listed_files(const fs::path& list) {
  std::vector<std::string> out;
  std::ifstream in(list);
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    out.push_back(line.substr(line.find(' ') + 1));
  }
  return out;
}

// The lab with a stereo pair, stronger depth noise and two exposure steps inside the first
// second, so one second exercises every frame effect.
ScenarioSpec stereo_lab_with_exposure_steps() {
  auto s = parse_scenario_yaml(
      "base: lab\n"
      "name: lab-live-test\n"
      "seed: 7\n"
      "camera: {stereo: {enabled: true, baseline_m: 0.12}}\n"
      "depth_noise: {sigma_quad_per_m: 0.004, hole_fraction: 0.03}\n"
      "exposure:\n"
      "  events:\n"
      "    - {time_s: 0.3, gain: 0.6}\n"
      "    - {time_s: 0.6, gain: 1.3}\n",
      "lab-live-test");
  EXPECT_TRUE(s.ok()) << s.status().to_string();
  return s.value();
}

bool same_data(const cv::Mat& a, const cv::Mat& b) {
  return a.size() == b.size() && a.type() == b.type() && cv::norm(a, b, cv::NORM_INF) == 0.0;
}

TEST(SimLiveLog, GivenAStereoLabSecondWhenRenderedLiveThenEveryFrameEqualsTheWrittenOneAndReplays) {
  const ScenarioSpec spec = stereo_lab_with_exposure_steps();
  const fs::path dir = scratch("frames");
  RunOptions opt;
  opt.out_dir = dir.string();
  opt.duration_s = 1.0;
  opt.threads = 2;  // the files are identical for any thread count
  auto summary = write_run(spec, opt);
  ASSERT_TRUE(summary.ok()) << summary.status().to_string();
  auto written = open_sim_run_log(dir.string());
  ASSERT_TRUE(written.ok()) << written.status().to_string();
  auto live = open_sim_live_log(spec, 1.0);
  ASSERT_TRUE(live.ok()) << live.status().to_string();

  // Source description: what the written run says, plus the stereo pair.
  const hal::SourceInfo& wi = written->log.info;
  const hal::SourceInfo& li = live->log.info;
  EXPECT_EQ(li.name, "sim-live:lab-live-test");
  EXPECT_TRUE(li.stereo);
  EXPECT_EQ(li.intrinsics.width, wi.intrinsics.width);
  EXPECT_EQ(li.intrinsics.height, wi.intrinsics.height);
  EXPECT_EQ(li.intrinsics.fx, wi.intrinsics.fx);
  EXPECT_EQ(li.intrinsics.cy, wi.intrinsics.cy);
  EXPECT_TRUE(li.T_imu_cam.isApprox(wi.T_imu_cam, 1e-15));
  EXPECT_EQ(li.camera_rate_hz, wi.camera_rate_hz);
  EXPECT_EQ(li.imu_rate_hz, wi.imu_rate_hz);
  EXPECT_EQ(li.has_imu, wi.has_imu);
  EXPECT_EQ(li.has_mag, wi.has_mag);
  EXPECT_EQ(li.has_gnss, wi.has_gnss);
  EXPECT_EQ(li.first_t_ns, wi.first_t_ns);
  EXPECT_EQ(li.last_t_ns, wi.last_t_ns);
  EXPECT_EQ(sim_calibration_to_yaml(live->calibration), slurp(dir / "calibration.yaml"));
  EXPECT_NEAR(live->path_length_m, summary->path_length_m, 1e-12);
  ASSERT_EQ(live->log.frame_t_ns, written->log.frame_t_ns);
  const size_t n = live->log.frame_t_ns.size();
  ASSERT_EQ(n, summary->frames);
  ASSERT_EQ(n, 31u);

  // Every frame, rendered into buffers sized once: the renderer and effects write in place.
  const std::vector<std::string> right_files = listed_files(dir / "right.txt");
  ASSERT_EQ(right_files.size(), n);
  const hal::PinholeIntrinsics& K = li.intrinsics;
  hal::RgbdFrame lf, wf;
  lf.bgr.create(K.height, K.width, CV_8UC3);
  lf.depth_m.create(K.height, K.width, CV_32FC1);
  lf.right_gray.create(K.height, K.width, CV_8UC1);
  const uchar* bgr_data = lf.bgr.data;
  const uchar* depth_data = lf.depth_m.data;
  const uchar* right_data = lf.right_gray.data;
  const double depth_scale = written->calibration.depth_scale;
  std::vector<cv::Scalar> bgr_sums(n);
  for (size_t k = 0; k < n; ++k) {
    SCOPED_TRACE("frame " + std::to_string(k));
    ASSERT_TRUE(live->log.load_frame(k, &lf).ok());
    ASSERT_TRUE(written->log.load_frame(k, &wf).ok());
    EXPECT_EQ(lf.bgr.data, bgr_data);
    EXPECT_EQ(lf.depth_m.data, depth_data);
    EXPECT_EQ(lf.right_gray.data, right_data);
    EXPECT_EQ(lf.t_ns, wf.t_ns);
    EXPECT_EQ(lf.seq, wf.seq);
    EXPECT_EQ(lf.intrinsics.fx, wf.intrinsics.fx);
    EXPECT_EQ(lf.intrinsics.width, wf.intrinsics.width);
    EXPECT_TRUE(same_data(lf.bgr, wf.bgr)) << "colour differs from rgb/ PNG";
    // Depth: the PNG holds round(depth * scale), so they differ by at most half a raw unit.
    ASSERT_EQ(lf.depth_m.type(), CV_32FC1);
    EXPECT_LE(cv::norm(lf.depth_m, wf.depth_m, cv::NORM_INF), 0.5 / depth_scale + 1e-6);
    EXPECT_GT(cv::norm(lf.depth_m, wf.depth_m, cv::NORM_INF), 0.0) << "live depth is not quantised";
    cv::Mat live_invalid = lf.depth_m == 0.0f, written_invalid = wf.depth_m == 0.0f;
    EXPECT_EQ(cv::countNonZero(live_invalid != written_invalid), 0) << "invalid pixels differ";
    EXPECT_EQ(lf.invalid_depth_px, wf.invalid_depth_px);
    EXPECT_GT(lf.invalid_depth_px, 0u) << "the noisy depth has holes";
    const cv::Mat right = cv::imread((dir / right_files[k]).string(), cv::IMREAD_UNCHANGED);
    EXPECT_TRUE(same_data(lf.right_gray, right)) << "right image differs from " << right_files[k];
    bgr_sums[k] = cv::sum(lf.bgr);
  }
  EXPECT_NE(bgr_sums.front(), bgr_sums[15]) << "the exposure step at 0.3 s changes the image";

  // Replay: every frame in order, rendered on the prefetch thread into the pool's frames.
  hal::SensorStreamsConfig cfg;
  cfg.width = K.width;
  cfg.height = K.height;
  cfg.stereo = li.stereo;
  hal::SensorStreams streams(cfg);
  const int64_t t0 = li.first_t_ns;
  const size_t n_imu = live->log.imu.size(), n_mag = live->log.mag.size();
  const std::vector<int64_t> frame_t_ns = live->log.frame_t_ns;
  auto src = hal::ReplaySource::create(std::move(live->log), &streams);
  ASSERT_TRUE(src.ok()) << src.status().to_string();
  size_t frames = 0, imu = 0, mag = 0;
  for (int64_t t = t0; !src.value()->finished(); t += 5'000'000) {
    ASSERT_TRUE(src.value()->poll(t, &streams).ok());
    hal::ImuSample s;
    while (streams.imu.try_pop(s)) ++imu;
    hal::MagSample m;
    while (streams.mag.try_pop(m)) ++mag;
    hal::RgbdFrame* f = nullptr;
    while (streams.frames.try_pop(f)) {
      EXPECT_EQ(f->seq, frames);
      if (f->seq < n) {
        EXPECT_EQ(f->t_ns, frame_t_ns[f->seq]);
        EXPECT_EQ(cv::sum(f->bgr), bgr_sums[f->seq]);
      }
      EXPECT_EQ(f->right_gray.type(), CV_8UC1);
      ++frames;
      streams.frame_pool.release(f);
    }
  }
  EXPECT_EQ(frames, n);
  EXPECT_EQ(imu, n_imu);
  EXPECT_EQ(mag, n_mag);
  EXPECT_EQ(src.value()->counters().frame_errors, 0u);
  EXPECT_EQ(src.value()->counters().frames_dropped, 0u);
  src.value().reset();
  fs::remove_all(dir);
}

// Relative tolerance of a number printed with `digits` significant digits.
double printed(double x, int digits) { return std::max(1.0, std::abs(x)) * std::pow(10.0, 1 - digits); }

TEST(SimLiveLog, GivenAMinuteOutdoorsWithGnssOutagesWhenOpenedLiveThenSamplesAndTruthEqualTheFiles) {
  auto spec = load_scenario(std::string(HWR_SOURCE_DIR) + "/scenarios/outdoor_gnss_dropouts.yaml");
  ASSERT_TRUE(spec.ok()) << spec.status().to_string();
  const double duration_s = 60.0;  // the configured outage 40-70 s begins inside
  const fs::path dir = scratch("streams");
  RunOptions opt;
  opt.out_dir = dir.string();
  opt.duration_s = duration_s;
  opt.write_images = false;
  auto summary = write_run(spec.value(), opt);
  ASSERT_TRUE(summary.ok()) << summary.status().to_string();
  auto written = open_sim_run_log(dir.string());
  ASSERT_TRUE(written.ok()) << written.status().to_string();
  auto live = open_sim_live_log(spec.value(), duration_s);
  ASSERT_TRUE(live.ok()) << live.status().to_string();
  const hal::ReplayLog& L = live->log;
  const hal::ReplayLog& W = written->log;

  // IMU (imu.csv prints %.12g), magnetometer (%.9g).
  ASSERT_EQ(L.imu.size(), W.imu.size());
  ASSERT_EQ(L.imu.size(), summary->imu_samples);
  for (size_t k = 0; k < L.imu.size(); ++k) {
    ASSERT_EQ(L.imu[k].t_ns, W.imu[k].t_ns);
    for (int i = 0; i < 3; ++i) {
      ASSERT_NEAR(L.imu[k].gyro_radps[i], W.imu[k].gyro_radps[i], printed(W.imu[k].gyro_radps[i], 12));
      ASSERT_NEAR(L.imu[k].accel_mps2[i], W.imu[k].accel_mps2[i], printed(W.imu[k].accel_mps2[i], 12));
    }
  }
  ASSERT_EQ(L.mag.size(), W.mag.size());
  ASSERT_EQ(L.mag.size(), summary->mag_samples);
  for (size_t k = 0; k < L.mag.size(); ++k) {
    ASSERT_EQ(L.mag[k].t_ns, W.mag[k].t_ns);
    for (int i = 0; i < 3; ++i)
      ASSERT_NEAR(L.mag[k].field_uT[i], W.mag[k].field_uT[i], printed(W.mag[k].field_uT[i], 9));
  }
  // GNSS (lat/lon %.10f, height %.4f, accuracies %.3f; nan during outages).
  ASSERT_EQ(L.gnss.size(), W.gnss.size());
  ASSERT_EQ(L.gnss.size(), summary->gnss_samples);
  size_t outages = 0;
  for (size_t k = 0; k < L.gnss.size(); ++k) {
    const hal::GnssFix &l = L.gnss[k], &w = W.gnss[k];
    ASSERT_EQ(l.t_ns, w.t_ns);
    ASSERT_EQ(l.fix_type, w.fix_type);
    ASSERT_EQ(l.num_sv, w.num_sv);
    if (w.fix_type == 0) {
      ++outages;
      EXPECT_TRUE(std::isnan(l.lat_deg) && std::isnan(w.lat_deg));
      continue;
    }
    ASSERT_NEAR(l.lat_deg, w.lat_deg, 5e-11);
    ASSERT_NEAR(l.lon_deg, w.lon_deg, 5e-11);
    ASSERT_NEAR(l.height_m, w.height_m, 5e-5);
    ASSERT_NEAR(l.h_acc_m, w.h_acc_m, 5e-4);
    ASSERT_NEAR(l.v_acc_m, w.v_acc_m, 5e-4);
  }
  EXPECT_GE(outages, 5u * 20u - 1u) << "the 40-70 s outage is in the minute";
  EXPECT_TRUE(L.info.has_gnss && L.info.has_mag && L.info.has_imu);
  EXPECT_FALSE(L.info.stereo);
  EXPECT_EQ(L.info.first_t_ns, W.info.first_t_ns);
  EXPECT_EQ(L.info.last_t_ns, W.info.last_t_ns);
  EXPECT_EQ(sim_calibration_to_yaml(live->calibration), slurp(dir / "calibration.yaml"));
  EXPECT_NEAR(live->path_length_m, summary->path_length_m, 1e-12);

  // Ground truth: written the way hwr-sim writes it, the very same bytes.
  const fs::path gt_file = dir / "live_groundtruth.txt";
  ASSERT_TRUE(core::write_tum_trajectory(gt_file.string(), live->groundtruth_T_world_cam,
                                         "hwr-sim " + spec->name + ": T_world_cam at the IMU rate")
                  .ok());
  EXPECT_EQ(slurp(gt_file), slurp(dir / "groundtruth.txt"));

  // Frames: 30 Hz over the minute; the pose at each frame time equals the IMU-rate truth where
  // the instants coincide (every 3rd frame, 100 ms) and lies between its neighbours elsewhere.
  const std::vector<core::StampedPose>& gt = live->groundtruth_T_world_cam;
  const std::vector<core::StampedPose>& at_frames = live->groundtruth_T_world_cam_at_frames;
  ASSERT_EQ(L.frame_t_ns.size(), 1801u);
  ASSERT_EQ(at_frames.size(), L.frame_t_ns.size());
  size_t coincident = 0;
  for (size_t k = 0; k < at_frames.size(); ++k) {
    ASSERT_EQ(at_frames[k].t_ns, L.frame_t_ns[k]);
    ASSERT_EQ(L.frame_t_ns[k] - L.frame_t_ns[0], static_cast<int64_t>(std::llround(k * 1e6 / 30.0)) * 1000);
    const int64_t dt = at_frames[k].t_ns - gt[0].t_ns;
    const size_t j = static_cast<size_t>(dt / 5'000'000);  // IMU sample at or before (200 Hz)
    ASSERT_LT(j, gt.size());
    ASSERT_LE(gt[j].t_ns, at_frames[k].t_ns);
    const Eigen::Isometry3d& T = at_frames[k].T_world_body;
    if (gt[j].t_ns == at_frames[k].t_ns) {
      ++coincident;
      EXPECT_LT((T.translation() - gt[j].T_world_body.translation()).norm(), 1e-9);
      EXPECT_LT((T.linear() - gt[j].T_world_body.linear()).norm(), 1e-12);
      continue;
    }
    ASSERT_LT(j + 1, gt.size());
    const double a = static_cast<double>(at_frames[k].t_ns - gt[j].t_ns) /
                     static_cast<double>(gt[j + 1].t_ns - gt[j].t_ns);
    const Eigen::Vector3d p =
        (1 - a) * gt[j].T_world_body.translation() + a * gt[j + 1].T_world_body.translation();
    EXPECT_LT((T.translation() - p).norm(), 1e-4) << "frame " << k;
  }
  EXPECT_EQ(coincident, 601u);
  fs::remove_all(dir);
}

TEST(SimLiveLog, GivenBadScenariosWhenOpenedLiveThenTheErrorIsTheOneHwrSimGives) {
  const ScenarioSpec lab = builtin_scenario("lab").value();
  std::vector<std::pair<std::string, ScenarioSpec>> bad;
  bad.push_back({"camera rate 0", lab});
  bad.back().second.camera.rate_hz = 0.0;
  bad.push_back({"one waypoint", lab});
  bad.back().second.trajectory.waypoints.resize(1);
  bad.push_back({"negative box", lab});
  bad.back().second.scene.boxes.at(0).size_m = Eigen::Vector3d(-1.0, 1.0, 1.0);
  const fs::path dir = scratch("errors");
  for (const auto& [what, spec] : bad) {
    SCOPED_TRACE(what);
    RunOptions opt;
    opt.out_dir = dir.string();
    opt.duration_s = 0.1;
    const auto w = write_run(spec, opt);
    const auto l = open_sim_live_log(spec, 0.1);
    ASSERT_FALSE(w.ok());
    ASSERT_FALSE(l.ok());
    EXPECT_EQ(l.status().code(), w.status().code());
    EXPECT_EQ(l.status().message(), w.status().message());
    EXPECT_FALSE(l.status().message().empty());
  }
  fs::remove_all(dir);
  const auto negative = open_sim_live_log(lab, -1.0);
  ASSERT_FALSE(negative.ok());
  EXPECT_EQ(negative.status().code(), core::ErrorCode::kInvalidArgument);
  EXPECT_NE(negative.status().message().find("duration_s"), std::string::npos) << negative.status().message();
}

}  // namespace
}  // namespace hwr::sim
