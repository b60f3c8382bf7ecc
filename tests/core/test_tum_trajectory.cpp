// TUM trajectory text files (core/tum_trajectory.hpp), on the real fr3/teddy ground truth and on
// hand-written text.

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "hwr/core/tum_trajectory.hpp"

namespace hwr::core {
namespace {

const std::string kTeddyGt = HWR_DATA_DIR "/tum-fr3-teddy-200/rgbd_dataset_freiburg3_teddy/groundtruth.txt";

std::filesystem::path temp_dir(const std::string& name) {
  const auto dir = std::filesystem::temp_directory_path() / ("hwr_test_tum_trajectory_" + name);
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

void expect_one_line(const Status& st) {
  EXPECT_FALSE(st.ok());
  EXPECT_EQ(st.message().find('\n'), std::string::npos) << st.message();
}

TEST(TumTrajectory, GivenTheTeddyGroundTruth_WhenRead_ThenCountsAndEndPosesMatchTheFile) {
  ASSERT_TRUE(std::filesystem::exists(kTeddyGt))
      << "dataset missing: " << kTeddyGt << " (see shared/data/README.md)";
  auto gt = read_tum_trajectory(kTeddyGt);
  ASSERT_TRUE(gt.ok()) << gt.status().to_string();
  ASSERT_EQ(gt->size(), 8080u);  // 8083 lines less 3 comment lines
  // First line: 1341841873.4151 -2.1837 0.6821 1.4854 -0.2651 0.7889 -0.5183 0.1970
  const StampedPose& first = gt->front();
  EXPECT_EQ(first.t_ns, 1341841873415100000LL);
  EXPECT_NEAR(first.T_world_body.translation().x(), -2.1837, 1e-12);
  EXPECT_NEAR(first.T_world_body.translation().y(), 0.6821, 1e-12);
  EXPECT_NEAR(first.T_world_body.translation().z(), 1.4854, 1e-12);
  const Eigen::Quaterniond q_file = Eigen::Quaterniond(0.1970, -0.2651, 0.7889, -0.5183).normalized();
  EXPECT_NEAR(Eigen::Quaterniond(first.T_world_body.linear()).angularDistance(q_file), 0.0, 1e-9);
  // Last line: 1341841954.2045 -2.2771 -0.7193 1.7563 ...
  EXPECT_EQ(gt->back().t_ns, 1341841954204500000LL);
  EXPECT_NEAR(gt->back().T_world_body.translation().y(), -0.7193, 1e-12);
  for (const StampedPose& p : *gt) {
    EXPECT_NEAR(
        (p.T_world_body.linear().transpose() * p.T_world_body.linear() - Eigen::Matrix3d::Identity()).norm(),
        0.0, 1e-12);
  }
}

TEST(TumTrajectory, GivenCommentsBlankLinesTabsAndCrlf_WhenParsed_ThenOnlyPosesAreKept) {
  const std::string text =
      "# header\r\n"
      "\r\n"
      "   # indented comment\n"
      "1.5\t1 2 3  0 0 0 1\r\n"
      "  2.0 4 5 6 0 0 0.7071067811865476 0.7071067811865476\n"
      "\n";
  auto t = parse_tum_trajectory(text, "mem.txt");
  ASSERT_TRUE(t.ok()) << t.status().to_string();
  ASSERT_EQ(t->size(), 2u);
  EXPECT_EQ((*t)[0].t_ns, 1'500'000'000LL);
  EXPECT_EQ((*t)[1].t_ns, 2'000'000'000LL);
  EXPECT_TRUE((*t)[0].T_world_body.translation().isApprox(Eigen::Vector3d(1, 2, 3)));
  // qz = qw = 1/sqrt(2): 90 degrees about z maps x to y.
  EXPECT_TRUE(
      ((*t)[1].T_world_body.linear() * Eigen::Vector3d::UnitX()).isApprox(Eigen::Vector3d::UnitY(), 1e-12));
}

TEST(TumTrajectory, GivenANearlyUnitQuaternion_WhenParsed_ThenItIsNormalised) {
  auto t = parse_tum_trajectory("0 0 0 0 0 0 0 1.005\n", "mem.txt");
  ASSERT_TRUE(t.ok()) << t.status().to_string();
  EXPECT_NEAR((t->front().T_world_body.linear() - Eigen::Matrix3d::Identity()).norm(), 0.0, 1e-15);
}

struct BadText {
  const char* text;
  const char* expect_in_message;
};

TEST(TumTrajectory, GivenMalformedLines_WhenParsed_ThenOneLineErrorNamesFileLineAndProblem) {
  const BadText cases[] = {
      {"# c\n1 2 3 4 5\n", "mem.txt:2: expected 8 numbers"},
      {"1 2 3 4 0 0 0 1 9\n", "got 9 or more"},
      {"abc 0 0 0 0 0 0 1\n", "mem.txt:1: bad timestamp 'abc'"},
      {"1 0 x 0 0 0 0 1\n", "mem.txt:1: field 3: not a finite number: 'x'"},
      {"1 0 nan 0 0 0 0 1\n", "field 3: not a finite number"},
      {"1 0 0 0 0 0 0 1.5\n", "mem.txt:1: quaternion norm"},
      {"1 0 0 0 0 0 0 0\n", "quaternion norm"},
      {"2 0 0 0 0 0 0 1\n1 0 0 0 0 0 0 1\n", "mem.txt:2: timestamps must increase"},
      {"1 0 0 0 0 0 0 1\n1 0 0 0 0 0 0 1\n", "mem.txt:2: timestamps must increase"},
  };
  for (const BadText& c : cases) {
    auto t = parse_tum_trajectory(c.text, "mem.txt");
    ASSERT_FALSE(t.ok()) << c.text;
    EXPECT_EQ(t.status().code(), ErrorCode::kParseError);
    EXPECT_NE(t.status().message().find(c.expect_in_message), std::string::npos)
        << "message: " << t.status().message() << "\nexpected to contain: " << c.expect_in_message;
    expect_one_line(t.status());
  }
}

TEST(TumTrajectory, GivenAMissingFileOrAFolder_WhenRead_ThenErrorNamesThePath) {
  auto missing = read_tum_trajectory("/nonexistent/hwr/traj.txt");
  ASSERT_FALSE(missing.ok());
  EXPECT_EQ(missing.status().code(), ErrorCode::kNotFound);
  EXPECT_NE(missing.status().message().find("/nonexistent/hwr/traj.txt"), std::string::npos);
  expect_one_line(missing.status());

  const auto dir = temp_dir("folder");
  auto folder = read_tum_trajectory(dir.string());
  ASSERT_FALSE(folder.ok()) << "a folder must not read as an empty trajectory";
  EXPECT_NE(folder.status().message().find(dir.string()), std::string::npos);
  expect_one_line(folder.status());
}

TEST(TumTrajectory, GivenPoses_WhenWrittenAndReadBack_ThenStampsAreExactAndPosesAgreeToNanometres) {
  std::vector<StampedPose> poses;
  for (int k = 0; k < 50; ++k) {
    StampedPose p;
    p.t_ns = 1341841873415100000LL + k * 33'333'333LL + (k % 7);  // odd nanoseconds survive
    p.T_world_body.linear() = (Eigen::AngleAxisd(0.1 * k, Eigen::Vector3d(1, 2, 3).normalized()) *
                               Eigen::AngleAxisd(3.0, Eigen::Vector3d::UnitX()))
                                  .toRotationMatrix();
    p.T_world_body.translation() = Eigen::Vector3d(std::sin(k) * 10, -k * 0.123456789, 1e-3 * k);
    poses.push_back(p);
  }
  const auto dir = temp_dir("roundtrip");
  const std::string path = (dir / "traj.txt").string();
  ASSERT_TRUE(write_tum_trajectory(path, poses, "written by test").ok());
  auto back = read_tum_trajectory(path);
  ASSERT_TRUE(back.ok()) << back.status().to_string();
  ASSERT_EQ(back->size(), poses.size());
  for (size_t k = 0; k < poses.size(); ++k) {
    EXPECT_EQ((*back)[k].t_ns, poses[k].t_ns);
    EXPECT_LT(((*back)[k].T_world_body.translation() - poses[k].T_world_body.translation()).norm(), 1e-9);
    EXPECT_LT(Eigen::Quaterniond((*back)[k].T_world_body.linear())
                  .angularDistance(Eigen::Quaterniond(poses[k].T_world_body.linear())),
              1e-11);
  }
  std::ifstream f(path);
  std::string first_line;
  std::getline(f, first_line);
  EXPECT_EQ(first_line, "# written by test");
}

TEST(TumTrajectory, GivenNegativeTimestamps_WhenWrittenAndReadBack_ThenTheyAreExact) {
  std::vector<StampedPose> poses(3);
  poses[0].t_ns = -2'000'000'001LL;
  poses[1].t_ns = -1;
  poses[2].t_ns = 0;
  const auto dir = temp_dir("negative");
  const std::string path = (dir / "traj.txt").string();
  ASSERT_TRUE(write_tum_trajectory(path, poses).ok());
  auto back = read_tum_trajectory(path);
  ASSERT_TRUE(back.ok()) << back.status().to_string();
  ASSERT_EQ(back->size(), 3u);
  for (size_t k = 0; k < 3; ++k) EXPECT_EQ((*back)[k].t_ns, poses[k].t_ns);
}

TEST(TumTrajectory, GivenAnUnwritablePath_WhenWritten_ThenIoErrorNamesIt) {
  const Status st = write_tum_trajectory("/nonexistent/hwr/out.txt", {});
  ASSERT_FALSE(st.ok());
  EXPECT_EQ(st.code(), ErrorCode::kIoError);
  EXPECT_NE(st.message().find("/nonexistent/hwr/out.txt"), std::string::npos);
}

}  // namespace
}  // namespace hwr::core
