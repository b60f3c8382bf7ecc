// hwr-eval ae, run as a program on a weld ground truth and a cloud file written here byte by byte
// (the format of recon/plate_fit.hpp: 16-byte little-endian records), so the test also checks the
// file format against an independent writer.

#include <unistd.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <random>
#include <sstream>
#include <string>
#include <tuple>
#include <vector>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "cli_run.hpp"
#include "hwr/core/tum_trajectory.hpp"

namespace {

namespace fs = std::filesystem;
using hwr::testing::CliRun;

const std::string kEval = HWR_BINARY_DIR "/apps/hwr-eval/hwr-eval";

using hwr::testing::key_values;

std::string num(double v) {
  char buf[40];
  std::snprintf(buf, sizeof(buf), "%.17g", v);
  return buf;
}

struct Plate {
  std::string name;
  Eigen::Vector3d size_m;
  Eigen::Isometry3d T_world_plate;
};

// weld_groundtruth.yaml as hwr-sim writes it.
std::string weld_yaml(const std::vector<Plate>& plates) {
  std::string y = "frame: world\nscenario: \"cli\"\nplates:\n";
  for (const Plate& p : plates) {
    y += "  - name: \"" + p.name + "\"\n    size_m: [" + num(p.size_m.x()) + ", " + num(p.size_m.y()) + ", " +
         num(p.size_m.z()) + "]\n    T_world_plate: [";
    const Eigen::Matrix4d M = p.T_world_plate.matrix();
    for (int i = 0; i < 16; ++i) y += (i ? ", " : "") + num(M(i / 4, i % 4));
    y += "]\n    corners_world: [";
    for (int i = 0; i < 8; ++i) {
      const Eigen::Vector3d local(((i >> 2) & 1 ? 0.5 : -0.5) * p.size_m.x(),
                                  ((i >> 1) & 1 ? 0.5 : -0.5) * p.size_m.y(),
                                  (i & 1 ? 0.5 : -0.5) * p.size_m.z());
      const Eigen::Vector3d c = p.T_world_plate * local;
      y += (i ? ", " : "") + num(c.x()) + ", " + num(c.y()) + ", " + num(c.z());
    }
    y += "]\n";
  }
  y += "seams:\n  - name: \"pair\"\n    type: butt\n    start_world: [0, 0, 0]\n    end_world: [1, 0, 0]\n"
       "    plates: [\"" +
       plates[0].name + "\", \"" + plates[1].name + "\"]\n";
  return y;
}

void put_f32(float f, std::string* out) {
  uint32_t u;
  std::memcpy(&u, &f, 4);
  for (int i = 0; i < 4; ++i) out->push_back(static_cast<char>((u >> (8 * i)) & 0xFF));
}

std::string cloud_bytes(const std::vector<Eigen::Vector3d>& pts) {
  std::string b;
  for (const Eigen::Vector3d& p : pts) {
    put_f32(static_cast<float>(p.x()), &b);
    put_f32(static_cast<float>(p.y()), &b);
    put_f32(static_cast<float>(p.z()), &b);
    b += std::string("\x80\x80\x80\x00", 4);
  }
  return b;
}

void write(const fs::path& path, const std::string& bytes) { std::ofstream(path, std::ios::binary) << bytes; }

class HwrEvalAe : public ::testing::Test {
 protected:
  void SetUp() override {
    ASSERT_TRUE(fs::exists(kEval)) << kEval << " not built: build the hwr-eval target before hwr_apps_tests";
    dir_ = fs::temp_directory_path() / ("hwr_eval_ae_" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    T.translation() = Eigen::Vector3d(2.0, -1.0, -0.345);
    plates_.push_back({"seen/left", Eigen::Vector3d(0.5, 0.25, 0.01), T});
    T.translation() = Eigen::Vector3d(8.0, 5.0, -0.345);
    plates_.push_back({"unseen/right", Eigen::Vector3d(0.5, 0.25, 0.01), T});
    write(dir_ / "weld.yaml", weld_yaml(plates_));
    // The top face of the first plate, 2 mm spacing, 1 mm noise; a floor 1 cm lower around it.
    std::mt19937 rng(3);
    std::uniform_real_distribution<double> ux(-0.25, 0.25), uy(-0.125, 0.125), fx(-0.4, 0.4), fy(-0.3, 0.3);
    std::normal_distribution<double> noise(0.0, 0.001);
    const Plate& p = plates_[0];
    for (int i = 0; i < 31250; ++i) {
      const Eigen::Vector3d local(ux(rng), uy(rng), 0.005);
      points_.push_back(p.T_world_plate * local + Eigen::Vector3d(noise(rng), noise(rng), noise(rng)));
    }
    for (int i = 0; i < 10000; ++i) {
      const Eigen::Vector3d local(fx(rng), fy(rng), -0.005);
      if (std::fabs(local.x()) < 0.25 && std::fabs(local.y()) < 0.125) continue;
      points_.push_back(p.T_world_plate * local + Eigen::Vector3d(noise(rng), noise(rng), noise(rng)));
    }
    write(dir_ / "cloud.bin", cloud_bytes(points_));
    gt_ = (dir_ / "weld.yaml").string();
    cloud_ = (dir_ / "cloud.bin").string();
  }
  void TearDown() override { fs::remove_all(dir_); }

  fs::path dir_;
  std::vector<Plate> plates_;
  std::vector<Eigen::Vector3d> points_;
  std::string gt_, cloud_;
};

TEST_F(HwrEvalAe, GivenACloudOfOneOfTwoPlatesThenKeyLinesReportItsErrorAndTheOtherUnseen) {
  const CliRun r = hwr::testing::run_cli(kEval, "ae --groundtruth " + gt_ + " --cloud " + cloud_);
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const auto kv = key_values(r.out);
  ASSERT_TRUE(kv.count("ae_mm")) << r.out;
  EXPECT_EQ(kv.at("plates_seen"), "1") << r.out;
  EXPECT_EQ(kv.at("plates_total"), "2");
  EXPECT_LT(std::stod(kv.at("ae_mm")), 2.0) << r.out;
  EXPECT_LT(std::stod(kv.at("ae_corner_mm")), 3.0) << r.out;
  EXPECT_NE(r.out.find("unseen/right"), std::string::npos);
  EXPECT_NE(r.out.find("not seen: 0 points in the ROI"), std::string::npos) << r.out;
}

TEST_F(HwrEvalAe, GivenVoxelMeansAndTheVoxelOptionThenTheErrorStaysSmall) {
  // 1 cm voxel means computed here (floor of p / 1 cm per axis, as recon::VoxelMap keys them).
  std::map<std::tuple<int64_t, int64_t, int64_t>, std::pair<Eigen::Vector3d, int>> cells;
  for (const Eigen::Vector3d& p : points_) {
    const std::tuple<int64_t, int64_t, int64_t> key{static_cast<int64_t>(std::floor(p.x() / 0.01)),
                                                    static_cast<int64_t>(std::floor(p.y() / 0.01)),
                                                    static_cast<int64_t>(std::floor(p.z() / 0.01))};
    auto& c = cells.try_emplace(key, Eigen::Vector3d::Zero(), 0).first->second;
    c.first += p;
    ++c.second;
  }
  std::vector<Eigen::Vector3d> means;
  for (const auto& kv : cells) means.push_back(kv.second.first / kv.second.second);
  write(dir_ / "voxels.bin", cloud_bytes(means));
  const CliRun r = hwr::testing::run_cli(
      kEval, "ae --groundtruth " + gt_ + " --cloud " + (dir_ / "voxels.bin").string() + " --voxel 0.01");
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const auto kv = key_values(r.out);
  EXPECT_EQ(kv.at("plates_seen"), "1") << r.out;
  EXPECT_LT(std::stod(kv.at("ae_mm")), 3.0) << r.out;
  EXPECT_LT(std::stod(kv.at("ae_corner_mm")), 3.0) << r.out;
  EXPECT_NE(r.out.find("voxel means of 0.01"), std::string::npos) << r.out;
}

TEST_F(HwrEvalAe, GivenACloudInTheEstimatesFrameThenAlignMovesItOntoTheGroundTruth) {
  // The estimate's frame is the world moved by T_est_world (1 m and 0.4 rad away); the cloud is
  // written in it. The trajectories: ground truth on a curve, the estimate the same poses in its frame.
  Eigen::Isometry3d T_est_world = Eigen::Isometry3d::Identity();
  T_est_world.linear() = Eigen::AngleAxisd(0.4, Eigen::Vector3d(0.2, 0.1, 1).normalized()).toRotationMatrix();
  T_est_world.translation() = Eigen::Vector3d(1.0, -0.5, 0.2);
  std::vector<hwr::core::StampedPose> gt(40), est(40);
  for (size_t k = 0; k < gt.size(); ++k) {
    const double s = static_cast<double>(k) / 10.0;
    gt[k].t_ns = 1'700'000'000'000'000'000LL + static_cast<int64_t>(k) * 100'000'000LL;
    gt[k].T_world_body.translation() = Eigen::Vector3d(s, 0.5 * s * s, 0.1 * std::sin(s));
    est[k] = gt[k];
    est[k].T_world_body = T_est_world * gt[k].T_world_body;
  }
  const std::string gt_traj = (dir_ / "gt.txt").string(), est_traj = (dir_ / "est.txt").string();
  ASSERT_TRUE(hwr::core::write_tum_trajectory(gt_traj, gt).ok());
  ASSERT_TRUE(hwr::core::write_tum_trajectory(est_traj, est).ok());
  std::vector<Eigen::Vector3d> moved;
  for (const Eigen::Vector3d& p : points_) moved.push_back(T_est_world * p);
  const std::string moved_cloud = (dir_ / "moved.bin").string();
  write(moved_cloud, cloud_bytes(moved));

  const CliRun plain = hwr::testing::run_cli(kEval, "ae --groundtruth " + gt_ + " --cloud " + moved_cloud);
  ASSERT_EQ(plain.exit_code, 0) << plain.out;
  EXPECT_EQ(key_values(plain.out).at("plates_seen"), "0") << plain.out;
  EXPECT_EQ(key_values(plain.out).at("ae_mm"), "nan");

  const CliRun aligned = hwr::testing::run_cli(
      kEval, "ae --groundtruth " + gt_ + " --cloud " + moved_cloud + " --align " + gt_traj + " " + est_traj);
  ASSERT_EQ(aligned.exit_code, 0) << aligned.out;
  const CliRun reference = hwr::testing::run_cli(kEval, "ae --groundtruth " + gt_ + " --cloud " + cloud_);
  const auto a = key_values(aligned.out), ref = key_values(reference.out);
  EXPECT_EQ(a.at("plates_seen"), "1") << aligned.out;
  // The same cloud up to float rounding of the moved coordinates.
  EXPECT_NEAR(std::stod(a.at("ae_mm")), std::stod(ref.at("ae_mm")), 0.05) << aligned.out;
  EXPECT_NEAR(std::stod(a.at("ae_corner_mm")), std::stod(ref.at("ae_corner_mm")), 0.05);
  EXPECT_NE(aligned.out.find("SE(3) of 40 poses"), std::string::npos) << aligned.out;
}

TEST_F(HwrEvalAe, GivenABrokenCloudOrGroundTruthThenOneLineErrorAndExitCode1) {
  write(dir_ / "short.bin", std::string(17, '\0'));
  CliRun r =
      hwr::testing::run_cli(kEval, "ae --groundtruth " + gt_ + " --cloud " + (dir_ / "short.bin").string());
  EXPECT_EQ(r.exit_code, 1) << r.out;
  EXPECT_NE(r.out.find("17 bytes is not a whole number of 16-byte point records"), std::string::npos)
      << r.out;

  std::string yaml = weld_yaml(plates_);
  const std::string size_line = "size_m: [0.5, 0.25, 0.01]";
  ASSERT_NE(yaml.find(size_line), std::string::npos);
  yaml.replace(yaml.find(size_line), size_line.size(), "size_m: [0.5, 0.25]");
  write(dir_ / "bad.yaml", yaml);
  r = hwr::testing::run_cli(kEval, "ae --groundtruth " + (dir_ / "bad.yaml").string() + " --cloud " + cloud_);
  EXPECT_EQ(r.exit_code, 1) << r.out;
  EXPECT_NE(r.out.find("bad.yaml:5: key 'plates[0].size_m': expected 3 numbers"), std::string::npos) << r.out;
}

TEST_F(HwrEvalAe, GivenBadUsageThenUsageAndExitCode2) {
  for (const std::string& args : {std::string("ae"), "ae --groundtruth " + gt_, "ae --cloud " + cloud_,
                                  "ae --groundtruth " + gt_ + " --cloud " + cloud_ + " --voxel -1",
                                  "ae --groundtruth " + gt_ + " --cloud " + cloud_ + " --align only_one",
                                  "ae --groundtruth " + gt_ + " --cloud " + cloud_ + " --bogus"}) {
    const CliRun r = hwr::testing::run_cli(kEval, args);
    EXPECT_EQ(r.exit_code, 2) << args << "\n" << r.out;
    EXPECT_NE(r.out.find("usage: hwr-eval"), std::string::npos) << args;
  }
}

}  // namespace
