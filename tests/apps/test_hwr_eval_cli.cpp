// hwr-eval, run as a program on trajectory files written here.

#include <unistd.h>

#include <bitset>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "cli_run.hpp"
#include "hwr/core/tum_trajectory.hpp"

namespace {

namespace fs = std::filesystem;
using hwr::core::StampedPose;
using hwr::testing::CliRun;

const std::string kEval = HWR_BINARY_DIR "/apps/hwr-eval/hwr-eval";

CliRun run_eval(const std::string& args) { return hwr::testing::run_cli(kEval, args); }

using hwr::testing::key_values;

class HwrEvalCli : public ::testing::Test {
 protected:
  void SetUp() override {
    ASSERT_TRUE(fs::exists(kEval)) << kEval << " not built: build the hwr-eval target before hwr_apps_tests";
    dir_ = fs::temp_directory_path() / ("hwr_eval_cli_" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    // Ground truth on a twisted cubic; the estimate is a rigid motion of it plus alternating
    // offsets of d along u with Thue-Morse signs, so ATE = d exactly (see the estimation tests).
    const size_t n = 64;
    const Eigen::Vector3d u = Eigen::Vector3d(0.3, 1, -0.2).normalized();
    Eigen::Isometry3d A = Eigen::Isometry3d::Identity();
    A.linear() = Eigen::AngleAxisd(0.9, Eigen::Vector3d(1, 0, 1).normalized()).toRotationMatrix();
    A.translation() = Eigen::Vector3d(3, 1, -2);
    std::vector<StampedPose> gt(n);
    std::vector<StampedPose> est(n);
    for (size_t k = 0; k < n; ++k) {
      const double s = static_cast<double>(k) / n;
      gt[k].t_ns = 1'700'000'000'000'000'000LL + static_cast<int64_t>(k) * 33'333'333LL;
      gt[k].T_world_body.translation() = Eigen::Vector3d(2 * s, 1.5 * s * s, s * s * s);
      const int sign = std::bitset<64>(k).count() % 2 == 0 ? 1 : -1;
      est[k] = gt[k];
      est[k].T_world_body.translation() += sign * kD * u;
      est[k].T_world_body = A.inverse() * est[k].T_world_body;
    }
    gt_ = (dir_ / "gt.txt").string();
    est_ = (dir_ / "est.txt").string();
    ASSERT_TRUE(hwr::core::write_tum_trajectory(gt_, gt).ok());
    ASSERT_TRUE(hwr::core::write_tum_trajectory(est_, est).ok());
  }
  void TearDown() override { fs::remove_all(dir_); }

  static constexpr double kD = 0.0125;
  fs::path dir_;
  std::string gt_;
  std::string est_;
};

TEST_F(HwrEvalCli, GivenAnEstimateWithKnownAte_WhenAteIsRun_ThenKeyValuesReportIt) {
  const CliRun r = run_eval("ate " + gt_ + " " + est_);
  ASSERT_EQ(r.exit_code, 0) << r.out;
  EXPECT_NE(r.out.find("ATE of"), std::string::npos) << r.out;
  const auto kv = key_values(r.out);
  ASSERT_TRUE(kv.count("ate_rmse_m")) << r.out;
  EXPECT_NEAR(std::stod(kv.at("ate_rmse_m")), kD, 1e-8);
  EXPECT_NEAR(std::stod(kv.at("ate_mean_m")), kD, 1e-8);
  EXPECT_NEAR(std::stod(kv.at("ate_median_m")), kD, 1e-8);
  EXPECT_NEAR(std::stod(kv.at("ate_max_m")), kD, 1e-8);
  EXPECT_NEAR(std::stod(kv.at("ate_std_m")), 0.0, 1e-8);
  EXPECT_EQ(kv.at("pairs"), "64");
  EXPECT_EQ(kv.at("scale"), "1.000000000");
}

TEST_F(HwrEvalCli, GivenSim3AndOptions_WhenAteIsRun_ThenTheyAreApplied) {
  const CliRun r = run_eval("ate " + gt_ + " " + est_ + " --sim3 --max-dt 0.01 --offset 0");
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const auto kv = key_values(r.out);
  EXPECT_EQ(kv.at("pairs"), "64");
  // Scale is free, so it can only do better than SE(3).
  EXPECT_LE(std::stod(kv.at("ate_rmse_m")), kD + 1e-9);
  EXPECT_NE(r.out.find("Sim(3)"), std::string::npos);
}

TEST_F(HwrEvalCli, GivenTwoTrajectories_WhenRpeIsRun_ThenKeyValuesArePrinted) {
  const CliRun self = run_eval("rpe " + gt_ + " " + gt_ + " --delta 4 --delta-unit f");
  ASSERT_EQ(self.exit_code, 0) << self.out;
  auto kv = key_values(self.out);
  EXPECT_EQ(kv.at("pairs"), "59");  // i + 4 < 63 for i = 0..58
  EXPECT_NEAR(std::stod(kv.at("rpe_trans_rmse_m")), 0.0, 1e-9);
  EXPECT_NEAR(std::stod(kv.at("rpe_rot_rmse_deg")), 0.0, 1e-9);

  const CliRun r = run_eval("rpe " + gt_ + " " + est_ + " --delta 0.5 --delta-unit s");
  ASSERT_EQ(r.exit_code, 0) << r.out;
  kv = key_values(r.out);
  ASSERT_TRUE(kv.count("rpe_trans_max_m")) << r.out;
  // Relative motions are off by at most the two endpoint offsets, 2d.
  EXPECT_LE(std::stod(kv.at("rpe_trans_max_m")), 2 * kD + 1e-9);
  EXPECT_GT(std::stod(kv.at("rpe_trans_max_m")), 0.0);
}

TEST_F(HwrEvalCli, GivenACorruptOrMissingFile_WhenRun_ThenOneLineErrorAndExitCode1) {
  const std::string bad = (dir_ / "bad.txt").string();
  std::ofstream(bad) << "# header\n1700000000.0 1 2 3 0 0 0 1\n1700000000.1 1 2 three 0 0 0 1\n";
  const CliRun r = run_eval("ate " + gt_ + " " + bad);
  EXPECT_EQ(r.exit_code, 1) << r.out;
  EXPECT_EQ(r.out, "hwr-eval: " + bad + ":3: field 4: not a finite number: 'three'\n");

  const CliRun missing = run_eval("rpe " + gt_ + " " + (dir_ / "nope.txt").string());
  EXPECT_EQ(missing.exit_code, 1);
  EXPECT_NE(missing.out.find("nope.txt"), std::string::npos);

  // Files fine, but no poses in common.
  const std::string far = (dir_ / "far.txt").string();
  std::ofstream(far) << "1.0 0 0 0 0 0 0 1\n2.0 0 0 0 0 0 0 1\n3.0 0 0 0 0 0 0 1\n";
  const CliRun none = run_eval("ate " + gt_ + " " + far);
  EXPECT_EQ(none.exit_code, 1);
  EXPECT_NE(none.out.find("at least 3 associated poses, found 0"), std::string::npos) << none.out;
}

TEST_F(HwrEvalCli, GivenBadUsage_WhenRun_ThenUsageAndExitCode2) {
  for (const std::string& args :
       {std::string(""), std::string("frobnicate a b"), "ate " + gt_, "ate " + gt_ + " " + est_ + " --max-dt",
        "ate " + gt_ + " " + est_ + " --max-dt x", "rpe " + gt_ + " " + est_ + " --delta-unit m",
        "ate " + gt_ + " " + est_ + " --delta 3", "rpe " + gt_ + " " + est_ + " --bogus"}) {
    const CliRun r = run_eval(args);
    EXPECT_EQ(r.exit_code, 2) << "args: " << args << "\n" << r.out;
    EXPECT_NE(r.out.find("usage: hwr-eval"), std::string::npos) << args;
  }
}

}  // namespace
