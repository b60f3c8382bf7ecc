// A run written by the simulator replays through the HAL exactly: every frame and sample, with the
// run's own calibration, and the decoded depth equals the written 16-bit depth / depth_scale.

#include <filesystem>
#include <fstream>
#include <string>

#include <unistd.h>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <gtest/gtest.h>

#include "hwr/hal/sensor_csv.hpp"
#include "hwr/sim/run_writer.hpp"
#include "hwr/sim/scenario.hpp"
#include "hwr/sim/sim_run_replay.hpp"

namespace hwr::sim {
namespace {

namespace fs = std::filesystem;

// The file named on the first non-comment line of a TUM list ("timestamp filename").
std::string first_listed_file(const fs::path& list) {
  std::ifstream in(list);
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    return line.substr(line.find(' ') + 1);
  }
  return {};
}

TEST(SimRunReplay, GivenAOneSecondLabRunWhenReplayedThenEveryFrameAndSampleArrives) {
  const fs::path dir = fs::temp_directory_path() / ("hwr_sim_replay_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  auto spec = builtin_scenario("lab");
  ASSERT_TRUE(spec.ok()) << spec.status().to_string();
  RunOptions opt;
  opt.out_dir = dir.string();
  opt.duration_s = 1.0;
  auto summary = write_run(spec.value(), opt);
  ASSERT_TRUE(summary.ok()) << summary.status().to_string();

  auto run = open_sim_run_log(dir.string());
  ASSERT_TRUE(run.ok()) << run.status().to_string();
  const hal::ReplayLog& log = run->log;
  EXPECT_EQ(log.frame_t_ns.size(), summary->frames);
  EXPECT_EQ(log.imu.size(), summary->imu_samples);
  EXPECT_EQ(log.mag.size(), summary->mag_samples);
  EXPECT_TRUE(log.info.has_imu);
  EXPECT_TRUE(log.info.T_imu_cam.isApprox(run->calibration.T_imu_cam, 1e-12));
  EXPECT_EQ(log.info.intrinsics.width, run->calibration.intrinsics.width);

  hal::SensorStreamsConfig cfg;
  cfg.width = log.info.intrinsics.width;
  cfg.height = log.info.intrinsics.height;
  hal::SensorStreams streams(cfg);
  const size_t n_frames = log.frame_t_ns.size();
  const int64_t t0 = log.info.first_t_ns;
  auto src = hal::ReplaySource::create(run->log, &streams);
  ASSERT_TRUE(src.ok());
  size_t frames = 0, imu = 0;
  bool checked_depth = false;
  for (int64_t t = t0; !src.value()->finished(); t += 5'000'000) {
    ASSERT_TRUE(src.value()->poll(t, &streams).ok());
    hal::ImuSample s;
    while (streams.imu.try_pop(s)) ++imu;
    hal::RgbdFrame* f = nullptr;
    while (streams.frames.try_pop(f)) {
      if (!checked_depth) {
        // Oracle: the first depth PNG the writer listed, raw / depth_scale.
        const cv::Mat raw =
            cv::imread((dir / first_listed_file(dir / "depth.txt")).string(), cv::IMREAD_UNCHANGED);
        ASSERT_EQ(raw.type(), CV_16UC1);
        cv::Mat expected;
        raw.convertTo(expected, CV_32FC1, 1.0 / run->calibration.depth_scale);
        EXPECT_EQ(cv::norm(expected, f->depth_m, cv::NORM_INF), 0.0);
        EXPECT_GT(cv::countNonZero(f->depth_m), static_cast<int>(f->depth_m.total() / 2))
            << "a lab view has depth";
        checked_depth = true;
      }
      ++frames;
      streams.frame_pool.release(f);
    }
  }
  EXPECT_EQ(frames, n_frames);
  EXPECT_EQ(imu, summary->imu_samples);
  src.value().reset();
  fs::remove_all(dir);
}

TEST(SimRunReplay, GivenAFolderWithoutCalibrationWhenOpenedThenItSaysWhatIsMissing) {
  const fs::path empty = fs::temp_directory_path() / ("hwr_sim_replay_empty_" + std::to_string(::getpid()));
  fs::create_directories(empty);
  auto run = open_sim_run_log(empty.string());
  fs::remove_all(empty);
  ASSERT_FALSE(run.ok());
  EXPECT_NE(run.status().message().find("no calibration.yaml"), std::string::npos) << run.status().message();
}

}  // namespace
}  // namespace hwr::sim
