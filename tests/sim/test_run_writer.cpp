// Run writer and hwr-sim (needs the renderer): every file is there and parses with the project's
// own readers, depth PNGs hold depth_m * depth_scale of the very render, any thread count gives
// the same bytes, the resolved scenario round-trips, and the CLI fails with one clear line.

#include <unistd.h>

#include <gtest/gtest.h>

#include <sys/wait.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <opencv2/imgcodecs.hpp>

#include "cross_run.hpp"
#include "hwr/core/config.hpp"
#include "hwr/core/time.hpp"
#include "hwr/core/tum_trajectory.hpp"
#include "hwr/hal/sensor_csv.hpp"
#include "hwr/hal/tum_dataset.hpp"
#include "hwr/sim/random.hpp"
#include "hwr/sim/run_writer.hpp"
#include "hwr/sim/sim_calibration.hpp"
#include "hwr/sim/world_frame.hpp"

namespace hwr::sim {
namespace {

namespace fs = std::filesystem;

std::string slurp(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

// A 1.5 s lab run that starts walking after 0.2 s (so frames differ from each other).
ScenarioSpec short_lab() {
  auto s = builtin_scenario("lab");
  EXPECT_TRUE(s.ok());
  ScenarioSpec spec = s.value();
  spec.trajectory.waypoints.front().dwell_s = 0.2;
  spec.duration_s = 1.5;
  return spec;
}

class RunWriter : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    // One folder per process: ctest runs each test of this suite in its own process, in parallel.
    root_ = fs::path(HWR_BINARY_DIR) / ("run_writer_test_" + std::to_string(::getpid()));
    fs::remove_all(root_);
    RunOptions o;
    o.out_dir = (root_ / "t1").string();
    o.threads = 1;
    auto r1 = write_run(short_lab(), o);
    ASSERT_TRUE(r1.ok()) << r1.status().to_string();
    summary_ = r1.value();
    o.out_dir = (root_ / "t2").string();
    o.threads = 2;
    auto r2 = write_run(short_lab(), o);
    ASSERT_TRUE(r2.ok()) << r2.status().to_string();
  }
  static void TearDownTestSuite() { fs::remove_all(root_); }

  static fs::path dir() { return root_ / "t1"; }
  static fs::path root_;
  static RunSummary summary_;
};
fs::path RunWriter::root_;
RunSummary RunWriter::summary_;

TEST_F(RunWriter, GivenShortLabRunWhenWrittenThenEveryFileExistsAndParsesWithTheProjectReaders) {
  const ScenarioSpec spec = short_lab();
  EXPECT_EQ(summary_.frames, 46u);  // 0 .. 1.5 s at 30 Hz
  EXPECT_EQ(summary_.imu_samples, 301u);
  EXPECT_EQ(summary_.mag_samples, 76u);
  EXPECT_EQ(summary_.gnss_samples, 0u);
  EXPECT_EQ(summary_.joints, spec.scene.joints.size());
  for (const char* f : {"rgb.txt", "depth.txt", "groundtruth.txt", "imu.csv", "imu_state_groundtruth.csv",
                        "mag.csv", "calibration.yaml", "weld_groundtruth.yaml", "scenario_resolved.yaml"}) {
    EXPECT_TRUE(fs::is_regular_file(dir() / f)) << f;
  }
  EXPECT_FALSE(fs::exists(dir() / "gnss.csv"));  // indoor: no GNSS
  for (const auto& e : fs::recursive_directory_iterator(dir())) {
    EXPECT_EQ(e.path().string().find(".tmp"), std::string::npos) << e.path();
  }
  // TUM lists: 3-line '#' header, then "timestamp rgb/<timestamp>.png".
  std::istringstream rgb(slurp(dir() / "rgb.txt"));
  std::string line;
  for (int i = 0; i < 3; ++i) {
    std::getline(rgb, line);
    EXPECT_EQ(line[0], '#');
  }
  std::getline(rgb, line);
  EXPECT_EQ(line, "1700000000.000000 rgb/1700000000.000000.png");
  std::getline(rgb, line);
  EXPECT_EQ(line, "1700000000.033333 rgb/1700000000.033333.png");
  // The project's TUM reader opens the folder and associates every pair.
  hal::TumDatasetOptions opt;
  opt.intrinsics = spec.camera.intrinsics;
  opt.depth_scale = spec.camera.depth_scale;
  opt.require_groundtruth = true;
  auto ds = hal::TumDataset::open(dir().string(), opt);
  ASSERT_TRUE(ds.ok()) << ds.status().to_string();
  EXPECT_EQ(ds->size(), summary_.frames);
  EXPECT_EQ(ds->groundtruth().size(), summary_.imu_samples);
  // World = first IMU frame: the first camera pose is T_imu_cam.
  const Eigen::Isometry3d T_imu_cam = camera_T_imu_cam(spec.camera);
  EXPECT_LT((ds->groundtruth().front().T_world_body.matrix() - T_imu_cam.matrix()).norm(), 1e-9);

  auto gt_file = core::read_tum_trajectory((dir() / "groundtruth.txt").string());
  ASSERT_TRUE(gt_file.ok()) << gt_file.status().to_string();
  EXPECT_EQ(gt_file->size(), summary_.imu_samples);
  EXPECT_EQ(gt_file->back().t_ns, spec.start_time_ns + 1'500'000'000);

  auto imu = hal::read_imu_csv((dir() / "imu.csv").string());
  ASSERT_TRUE(imu.ok()) << imu.status().to_string();
  EXPECT_EQ(imu->size(), 301u);
  EXPECT_EQ(imu->front().t_ns, spec.start_time_ns);
  auto state = hal::read_euroc_state_csv((dir() / "imu_state_groundtruth.csv").string());
  ASSERT_TRUE(state.ok()) << state.status().to_string();
  EXPECT_LT(state->front().p_world_body.norm(), 1e-12);
  EXPECT_LT((state->front().gyro_bias_radps - spec.imu.noise.gyro_bias_initial_radps).norm(), 1e-12);
  // Ground truth of the camera and of the IMU agree through T_imu_cam.
  const auto& gt = ds->groundtruth();
  for (size_t k : {size_t{0}, size_t{150}, size_t{300}}) {
    const Eigen::Isometry3d T_world_cam = (*state)[k].T_world_body() * T_imu_cam;
    EXPECT_LT((T_world_cam.matrix() - gt[k].T_world_body.matrix()).norm(), 1e-7);
  }
  auto mag = hal::read_mag_csv((dir() / "mag.csv").string());
  ASSERT_TRUE(mag.ok()) << mag.status().to_string();
  EXPECT_EQ(mag->size(), 76u);
}

TEST_F(RunWriter, GivenDepthPngWhenComparedWithTheSameRenderThenRawIsDepthTimesScale) {
  const ScenarioSpec spec = short_lab();
  auto traj = Trajectory::build(spec.trajectory);
  ASSERT_TRUE(traj.ok());
  auto renderer = Renderer::create(spec.scene);
  ASSERT_TRUE(renderer.ok());
  const size_t k = 40;
  const int64_t t_off = 1'333'333'000;  // frame 40 at 30 Hz, in whole microseconds
  const std::string stamp = "1700000001.333333";
  cv::Mat bgr, depth;
  const Eigen::Isometry3d T_scene_cam =
      traj->evaluate(core::ns_to_s(t_off)).T_scene_imu * camera_T_imu_cam(spec.camera);
  renderer.value()->render(T_scene_cam, spec.camera.intrinsics, spec.render, &bgr, &depth);
  const cv::Mat clean = depth.clone();
  apply_depth_noise(spec.depth_noise, derive_seed(spec.seed, RandomStream::kDepthNoise, k), &depth);
  cv::Mat expect16;
  depth_to_u16(depth, spec.camera.depth_scale, &expect16);
  const cv::Mat png = cv::imread((dir() / "depth" / (stamp + ".png")).string(), cv::IMREAD_UNCHANGED);
  ASSERT_EQ(png.type(), CV_16UC1);
  ASSERT_EQ(png.size(), expect16.size());
  EXPECT_EQ(cv::countNonZero(png != expect16), 0);
  // The scale itself: a valid pixel reads back to the noisy metric depth within half a unit.
  int checked = 0;
  for (int r = 0; r < png.rows; r += 37) {
    for (int c = 0; c < png.cols; c += 41) {
      const uint16_t raw = png.at<uint16_t>(r, c);
      if (raw == 0) continue;
      EXPECT_NEAR(raw / spec.camera.depth_scale, depth.at<float>(r, c), 0.5 / spec.camera.depth_scale + 1e-6);
      // Against the clean render: within 5 sigma of the range-dependent noise (camera_effects.hpp).
      const double z = clean.at<float>(r, c);
      const double sigma = spec.depth_noise.sigma_const_m + spec.depth_noise.sigma_quad_per_m * z * z;
      EXPECT_NEAR(raw / spec.camera.depth_scale, z, 5.0 * sigma);
      ++checked;
    }
  }
  EXPECT_GT(checked, 100);
  // Colour: the render with the frame's exposure, bit for bit.
  ExposureSpec ex = spec.exposure;
  ex.gain = exposure_gain_at(spec, core::ns_to_s(t_off));
  apply_exposure(ex, derive_seed(spec.seed, RandomStream::kExposure, k), &bgr);
  const cv::Mat rgb = cv::imread((dir() / "rgb" / (stamp + ".png")).string(), cv::IMREAD_UNCHANGED);
  ASSERT_EQ(rgb.type(), CV_8UC3);
  cv::Mat diff;
  cv::absdiff(rgb, bgr, diff);
  EXPECT_EQ(cv::countNonZero(diff.reshape(1)), 0);
}

TEST_F(RunWriter, GivenOneAndTwoThreadsWhenFilesComparedThenTheyAreByteIdentical) {
  size_t files = 0;
  for (const auto& e : fs::recursive_directory_iterator(dir())) {
    if (!e.is_regular_file()) continue;
    const fs::path rel = fs::relative(e.path(), dir());
    ASSERT_TRUE(fs::exists(root_ / "t2" / rel)) << rel;
    EXPECT_TRUE(slurp(e.path()) == slurp(root_ / "t2" / rel)) << rel;
    ++files;
  }
  EXPECT_EQ(files, 2 * summary_.frames + 9);
}

TEST_F(RunWriter, GivenResolvedScenarioAndCalibrationWhenLoadedBackThenTheyReproduceTheRun) {
  const ScenarioSpec spec = short_lab();
  const std::string resolved = slurp(dir() / "scenario_resolved.yaml");
  auto back = load_scenario((dir() / "scenario_resolved.yaml").string());
  ASSERT_TRUE(back.ok()) << back.status().to_string();
  EXPECT_EQ(scenario_to_yaml(back.value()), resolved);
  EXPECT_EQ(back->duration_s, 1.5);
  EXPECT_EQ(back->name, "lab");

  auto calib = load_sim_calibration((dir() / "calibration.yaml").string());
  ASSERT_TRUE(calib.ok()) << calib.status().to_string();
  auto traj = Trajectory::build(spec.trajectory);
  const Eigen::Isometry3d T_scene_world = world_frame_from_first_imu_pose(traj->evaluate(0).T_scene_imu);
  const SimCalibration want = make_sim_calibration(spec, T_scene_world);
  EXPECT_EQ(calib->scenario, "lab");
  EXPECT_EQ(calib->seed, spec.seed);
  EXPECT_EQ(calib->intrinsics.fx, 525.0);
  EXPECT_EQ(calib->depth_scale, 5000.0);
  EXPECT_EQ(calib->imu_rate_hz, 200.0);
  EXPECT_EQ(calib->gyro_noise_density, spec.imu.noise.gyro_noise_density);
  EXPECT_LT((calib->T_imu_cam.matrix() - want.T_imu_cam.matrix()).norm(), 1e-12);
  EXPECT_LT((calib->T_scene_world.matrix() - T_scene_world.matrix()).norm(), 1e-12);
  EXPECT_LT((calib->mag_field_world_uT - want.mag_field_world_uT).norm(), 1e-12);
  EXPECT_FALSE(calib->gnss_enabled);
  // Strict: an unknown key is an error naming it.
  auto bad = parse_sim_calibration(slurp(dir() / "calibration.yaml") + "extra_key: 1\n", "calibration.yaml");
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.status().message().find("extra_key"), std::string::npos);
}

TEST_F(RunWriter, GivenWeldGroundTruthWhenParsedThenCornersAreTheSceneTruthInTheWorldFrame) {
  const ScenarioSpec spec = short_lab();
  auto doc = core::ConfigDocument::load_file((dir() / "weld_groundtruth.yaml").string());
  ASSERT_TRUE(doc.ok());
  core::ConfigMap root = doc->root();
  std::string frame, scenario;
  root.require("frame", &frame).require("scenario", &scenario);
  std::vector<core::ConfigMap> plates = root.list("plates");
  std::vector<core::ConfigMap> seams = root.list("seams");
  const SceneGroundTruth truth = scene_ground_truth(spec.scene);
  ASSERT_EQ(plates.size(), truth.plates.size());
  ASSERT_EQ(seams.size(), truth.seams.size());
  auto traj = Trajectory::build(spec.trajectory);
  const Eigen::Isometry3d T_world_scene =
      world_frame_from_first_imu_pose(traj->evaluate(0).T_scene_imu).inverse();
  for (size_t i = 0; i < plates.size(); ++i) {
    std::string name;
    Eigen::Vector3d size;
    std::vector<double> corners, T16;
    plates[i].require("name", &name).require("size_m", &size).require("corners_world", &corners);
    plates[i].require("T_world_plate", &T16);
    EXPECT_EQ(name, truth.plates[i].name);
    EXPECT_EQ(size, truth.plates[i].size_m);
    ASSERT_EQ(corners.size(), 24u);
    for (int c = 0; c < 8; ++c) {
      const Eigen::Vector3d w = T_world_scene * truth.plates[i].corners_scene[c];
      EXPECT_LT((Eigen::Vector3d(corners[3 * c], corners[3 * c + 1], corners[3 * c + 2]) - w).norm(), 1e-12);
    }
  }
  for (size_t i = 0; i < seams.size(); ++i) {
    std::string name, type;
    Eigen::Vector3d start, end;
    std::vector<double> names_unused;
    seams[i]
        .require("name", &name)
        .require("type", &type)
        .require("start_world", &start)
        .require("end_world", &end);
    seams[i].has("plates");
    EXPECT_EQ(name, truth.seams[i].name);
    EXPECT_LT((start - T_world_scene * truth.seams[i].start_scene).norm(), 1e-12);
    EXPECT_NEAR((end - start).norm(), spec.scene.joints[i].length_m, 1e-12);
  }
  EXPECT_EQ(frame, "world");
}

TEST(RunWriterStereo, GivenStereoScenarioWhenWrittenThenRightImagesAreGrayAndListed) {
  ScenarioSpec spec = short_lab();
  spec.camera.stereo = true;
  spec.duration_s = 0.1;
  RunOptions o;
  o.out_dir = std::string(HWR_BINARY_DIR) + "/run_writer_stereo_" + std::to_string(::getpid());
  fs::remove_all(o.out_dir);
  auto r = write_run(spec, o);
  ASSERT_TRUE(r.ok()) << r.status().to_string();
  EXPECT_EQ(r->frames, 4u);
  ASSERT_TRUE(fs::exists(o.out_dir + "/right.txt"));
  const cv::Mat right = cv::imread(o.out_dir + "/right/1700000000.000000.png", cv::IMREAD_UNCHANGED);
  EXPECT_EQ(right.type(), CV_8UC1);
  EXPECT_EQ(right.cols, 640);
  auto calib = load_sim_calibration(o.out_dir + "/calibration.yaml");
  ASSERT_TRUE(calib.ok());
  EXPECT_TRUE(calib->stereo);
  EXPECT_EQ(calib->baseline_m, 0.12);
  fs::remove_all(o.out_dir);
}

TEST(RunWriterErrors, GivenAnOutputPathUnderAFileWhenWrittenThenAnIoErrorNamesThePath) {
  const std::string file =
      std::string(HWR_BINARY_DIR) + "/run_writer_not_a_dir_" + std::to_string(::getpid());
  std::ofstream(file) << "x";
  RunOptions o;
  o.out_dir = file + "/out";
  o.write_images = false;
  auto r = write_run(short_lab(), o);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), core::ErrorCode::kIoError);
  EXPECT_NE(r.status().message().find(o.out_dir), std::string::npos) << r.status().message();
  fs::remove(file);
}

// ---------------------------------------------------------------------------------------- CLI
struct CliResult {
  int exit_code = -1;
  std::string stdout_text, stderr_text;
};

CliResult run_cli(const std::string& args) {
  const fs::path exe = fs::path(HWR_BINARY_DIR) / "apps/hwr-sim/hwr-sim";
  EXPECT_TRUE(fs::exists(exe)) << "build the hwr-sim target before the sim tests";
  const std::string out = std::string(HWR_BINARY_DIR) + "/sim_cli_" + std::to_string(::getpid()) + ".out",
                    err = std::string(HWR_BINARY_DIR) + "/sim_cli_" + std::to_string(::getpid()) + ".err";
  const int status = std::system(
      (hwr::test::emulated_command(exe.string()) + " " + args + " >" + out + " 2>" + err).c_str());
  CliResult r;
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  r.stdout_text = slurp(out);
  r.stderr_text = slurp(err);
  fs::remove(out);
  fs::remove(err);
  return r;
}

TEST(HwrSimCli, GivenUnknownScenarioWhenRunThenExitsOneWithOneClearLine) {
  const CliResult r = run_cli("--scenario labz --out " + std::string(HWR_BINARY_DIR) + "/sim_cli_never");
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(r.stderr_text,
            "hwr-sim: unknown scenario 'labz' (built-in: lab, outdoor, lab-revisit, outdoor-revisit)\n");
  EXPECT_FALSE(fs::exists(std::string(HWR_BINARY_DIR) + "/sim_cli_never"));
}

TEST(HwrSimCli, GivenUnwritableOutWhenRunThenExitsOneWithOneClearLine) {
  const std::string file = std::string(HWR_BINARY_DIR) + "/sim_cli_file_" + std::to_string(::getpid());
  std::ofstream(file) << "x";
  const CliResult r = run_cli("--scenario lab --no-images --out " + file + "/run");
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(std::count(r.stderr_text.begin(), r.stderr_text.end(), '\n'), 1) << r.stderr_text;
  EXPECT_NE(r.stderr_text.find("hwr-sim: cannot create output folder '" + file + "/run'"), std::string::npos)
      << r.stderr_text;
  fs::remove(file);
}

TEST(HwrSimCli, GivenBadScenarioFileWhenRunThenExitsOneNamingFileLineAndKey) {
  const std::string yaml =
      std::string(HWR_BINARY_DIR) + "/sim_cli_bad_" + std::to_string(::getpid()) + ".yaml";
  std::ofstream(yaml) << "base: lab\ncamera:\n  fps: 30\n";
  const CliResult r =
      run_cli("--scenario " + yaml + " --out " + std::string(HWR_BINARY_DIR) + "/sim_cli_never");
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.stderr_text.find(yaml + ":3: unknown key 'camera.fps'"), std::string::npos) << r.stderr_text;
  fs::remove(yaml);
}

TEST(HwrSimCli, GivenSensorsOnlyRunWhenRunThenExitsZeroAndPrintsTheSummary) {
  const std::string out = std::string(HWR_BINARY_DIR) + "/sim_cli_ok";
  fs::remove_all(out);
  const CliResult r = run_cli("--scenario outdoor --no-images --duration 3 --out " + out);
  EXPECT_EQ(r.exit_code, 0) << r.stderr_text;
  EXPECT_NE(r.stdout_text.find("hwr-sim: outdoor: 0 frames, 3.0 s simulated"), std::string::npos)
      << r.stdout_text;
  EXPECT_TRUE(fs::exists(out + "/gnss.csv"));
  auto gnss = hal::read_gnss_csv(out + "/gnss.csv");
  ASSERT_TRUE(gnss.ok()) << gnss.status().to_string();
  EXPECT_EQ(gnss->size(), 16u);
  fs::remove_all(out);
}

}  // namespace
}  // namespace hwr::sim
