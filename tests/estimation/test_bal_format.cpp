// BAL reader / writer (estimation/bal_format.hpp) on the real Ladybug files, on corrupted copies,
// and in round trips.

#include <cmath>
#include <filesystem>
#include <string>

#include <gtest/gtest.h>

#include "hal/hal_test_util.hpp"
#include "hwr/core/file_io.hpp"
#include "hwr/core/so3.hpp"
#include "hwr/estimation/bal_format.hpp"
#include "hwr/estimation/ba_solver.hpp"

namespace hwr::estimation {
namespace {

using hal::testing::scratch_dir;
using hal::testing::write_text;

const std::string kBalDir = HWR_DATA_DIR "/bal-ladybug";
const std::string kLadybugFull = kBalDir + "/bal/ladybug/problem-49-7776-pre.txt";
const std::string kLadybug1800 = kBalDir + "/test/bal-ladybug-problem-49-7776-pre-shrink-1800.txt";

// The whole file (empty when it cannot be read: the comparisons then fail and say so).
std::string slurp(const std::string& path) {
  std::string text;
  if (!core::read_file(path, &text).ok()) text.clear();
  return text;
}

TEST(BalFormat, ReadsLadybug1800) {
  HWR_REQUIRE_DATASET(kBalDir);
  const auto pb = read_bal(kLadybug1800);
  ASSERT_TRUE(pb.ok()) << pb.status().to_string();
  EXPECT_EQ(pb->model, BaCameraModel::kBalRadial);
  EXPECT_EQ(pb->cameras.size(), 49u);
  EXPECT_EQ(pb->points.size(), 1800u);
  ASSERT_EQ(pb->observations.size(), 10863u);
  // First and last observation lines: "0 0 -3.326500e+02 2.620900e+02", "6 1799 -3.143900e+02 -1.450200e+02".
  EXPECT_EQ(pb->observations.front().camera, 0);
  EXPECT_EQ(pb->observations.front().point, 0);
  EXPECT_EQ(pb->observations.front().uv_px, Eigen::Vector2d(-332.65, 262.09));
  EXPECT_EQ(pb->observations.back().camera, 6);
  EXPECT_EQ(pb->observations.back().point, 1799);
  EXPECT_EQ(pb->observations.back().uv_px, Eigen::Vector2d(-314.39, -145.02));
  // Camera 0: angle-axis (1.574e-2, -1.279e-2, -4.40e-3), t (-3.409e-2, -1.075e-1, 1.1202), f 399.75.
  const BaCamera& c0 = pb->cameras[0];
  EXPECT_NEAR((core::so3_log(c0.T_cam_world.linear()) -
               Eigen::Vector3d(1.5741515942940262e-02, -1.2790936163850642e-02, -4.4008498081980789e-03))
                  .norm(),
              0.0, 1e-15);
  EXPECT_EQ(c0.T_cam_world.translation(),
            Eigen::Vector3d(-3.4093839577186584e-02, -1.0751387104921525e-01, 1.1202240291236032e+00));
  EXPECT_EQ(c0.K.f, 3.9975152639358436e+02);
  EXPECT_EQ(c0.K.k1, -3.1770643852803579e-07);
  EXPECT_EQ(c0.K.k2, 5.8820490534594022e-13);
  for (const BaCamera& c : pb->cameras) EXPECT_FALSE(c.fixed);
}

TEST(BalFormat, ReadsLadybugFull) {
  HWR_REQUIRE_DATASET(kBalDir);
  const auto pb = read_bal(kLadybugFull);
  ASSERT_TRUE(pb.ok()) << pb.status().to_string();
  EXPECT_EQ(pb->cameras.size(), 49u);
  EXPECT_EQ(pb->points.size(), 7776u);
  EXPECT_EQ(pb->observations.size(), 31843u);
}

TEST(BalFormat, RejectsTruncatedAndCorruptedCopies) {
  HWR_REQUIRE_DATASET(kBalDir);
  const std::string text = slurp(kLadybug1800);
  ASSERT_GT(text.size(), 100000u);
  const auto dir = scratch_dir("bal_corrupt");
  auto expect_error = [&](const std::string& content, const std::string& name, const std::string& fragment) {
    const std::string path = (dir / name).string();
    write_text(path, content);
    const auto pb = read_bal(path);
    ASSERT_FALSE(pb.ok()) << name;
    EXPECT_NE(pb.status().message().find(fragment), std::string::npos)
        << name << ": " << pb.status().to_string() << " (expected '" << fragment << "')";
    EXPECT_NE(pb.status().message().find(name), std::string::npos) << "the message names the file";
  };
  // Truncated at several places (whole tokens lost).
  for (const double f : {0.0, 0.001, 0.1, 0.5, 0.9, 0.99}) {
    const size_t n = static_cast<size_t>(f * static_cast<double>(text.size()));
    expect_error(text.substr(0, n), "trunc_" + std::to_string(n) + ".txt", n == 0 ? "ends before" : "");
  }
  expect_error(text.substr(0, text.size() - 40), "trunc_end.txt", "file ends before point coordinate");
  auto replace_line = [&](int line, const std::string& with) {
    std::string t = text;
    size_t pos = 0;
    for (int i = 1; i < line; ++i) pos = t.find('\n', pos) + 1;
    const size_t end = t.find('\n', pos);
    return t.replace(pos, end - pos, with);
  };
  expect_error(replace_line(1, "49 1800 1000000000000"), "absurd_count.txt", "outside [0, INT_MAX]");
  expect_error(replace_line(1, "49 1800 100000000"), "too_many_obs.txt", "more than a file");
  expect_error(replace_line(1, "49 -3 10863"), "negative_count.txt", "outside [0, INT_MAX]");
  expect_error(replace_line(1, "49 1799 10863"), "fewer_points.txt", "point index 1799 out of range");
  expect_error(replace_line(1, "49 1800 10862"), "fewer_obs.txt", "");
  expect_error(replace_line(3, "49 0 1.0 2.0"), "camera_range.txt", "camera index 49 out of range");
  expect_error(replace_line(3, "1 0 abc 2.0"), "not_number.txt", "got 'abc'");
  expect_error(replace_line(3, "1 0 1.0 nan"), "nan.txt", "finite number");
  expect_error(replace_line(3, "1.5 0 1.0 2.0"), "float_index.txt", "expected an integer");
  expect_error(text + "\n1.0\n", "trailing.txt", "trailing data");
  expect_error("", "empty.txt", "file ends before number of cameras");
  const auto missing = read_bal((dir / "does_not_exist.txt").string());
  ASSERT_FALSE(missing.ok());
  EXPECT_EQ(missing.status().code(), core::ErrorCode::kNotFound);
}

TEST(BalFormat, RoundTripIsExact) {
  HWR_REQUIRE_DATASET(kBalDir);
  const auto a = read_bal(kLadybug1800);
  ASSERT_TRUE(a.ok());
  const std::string path = (scratch_dir("bal_roundtrip") / "rt.txt").string();
  ASSERT_TRUE(write_bal(*a, path).ok());
  const auto b = read_bal(path);
  ASSERT_TRUE(b.ok()) << b.status().to_string();
  ASSERT_EQ(a->cameras.size(), b->cameras.size());
  ASSERT_EQ(a->points.size(), b->points.size());
  ASSERT_EQ(a->observations.size(), b->observations.size());
  for (size_t i = 0; i < a->observations.size(); ++i) {
    EXPECT_EQ(a->observations[i].camera, b->observations[i].camera);
    EXPECT_EQ(a->observations[i].point, b->observations[i].point);
    ASSERT_EQ(a->observations[i].uv_px, b->observations[i].uv_px) << i;
  }
  for (size_t i = 0; i < a->points.size(); ++i) ASSERT_EQ(a->points[i].p_world, b->points[i].p_world) << i;
  for (size_t c = 0; c < a->cameras.size(); ++c) {
    const BaCamera &ca = a->cameras[c], &cb = b->cameras[c];
    EXPECT_EQ(ca.T_cam_world.translation(), cb.T_cam_world.translation());
    // Rotation through angle-axis: exact to the last bits of so3_log / so3_exp.
    EXPECT_LT((ca.T_cam_world.linear() - cb.T_cam_world.linear()).cwiseAbs().maxCoeff(), 1e-15);
    EXPECT_EQ(ca.K.f, cb.K.f);
    EXPECT_EQ(ca.K.k1, cb.K.k1);
    EXPECT_EQ(ca.K.k2, cb.K.k2);
  }
  // And the text of a second write is stable.
  const std::string path2 = (scratch_dir("bal_roundtrip") / "rt2.txt").string();
  ASSERT_TRUE(write_bal(*b, path2).ok());
  const auto c = read_bal(path2);
  ASSERT_TRUE(c.ok());
  SparseBundleAdjuster solver({49, 1800, 10863});
  BaOptions opt;
  const double ca = solver.evaluate_cost(*a, opt), cc = solver.evaluate_cost(*c, opt);
  EXPECT_NEAR(ca, cc, 1e-10 * ca);
}

TEST(BalFormat, PinholeProblemIsConvertedWithTheSameGeometry) {
  // GIVEN a pinhole problem (fx != fy, cx, cy != 0) with known residuals
  BaProblem pb;
  pb.model = BaCameraModel::kPinhole;
  BaCamera cam;
  cam.K.fx = 500.0;
  cam.K.fy = 480.0;
  cam.K.cx = 320.0;
  cam.K.cy = 240.0;
  cam.T_cam_world.linear() = core::so3_exp(Eigen::Vector3d(0.1, -0.2, 0.3));
  cam.T_cam_world.translation() = Eigen::Vector3d(0.2, 0.1, -0.3);
  pb.cameras.push_back(cam);
  cam.T_cam_world.translation().x() += 0.5;
  pb.cameras.push_back(cam);
  for (int i = 0; i < 20; ++i) {
    BaPoint p;
    p.p_world = pb.cameras[0].T_cam_world.inverse() *
                Eigen::Vector3d(0.1 * (i % 5) - 0.2, 0.07 * (i / 5) - 0.1, 3.0 + 0.1 * i);
    pb.points.push_back(p);
    for (int c = 0; c < 2; ++c) {
      BaObservation o;
      o.camera = c;
      o.point = i;
      o.uv_px = ba_reprojection_residual(BaCameraModel::kPinhole, pb.cameras[static_cast<size_t>(c)],
                                         p.p_world, o) +
                Eigen::Vector2d(1.5, -0.5);  // residual (-1.5, 0.5) px
      pb.observations.push_back(o);
    }
  }
  const std::string path = (scratch_dir("bal_pinhole") / "pinhole.txt").string();
  ASSERT_TRUE(write_bal(pb, path).ok());
  const auto bal = read_bal(path);
  ASSERT_TRUE(bal.ok()) << bal.status().to_string();
  // THEN the BAL residuals are (u residual, -v residual * fx / fy).
  for (size_t i = 0; i < pb.observations.size(); ++i) {
    const BaObservation& o = bal->observations[i];
    const Eigen::Vector2d r =
        ba_reprojection_residual(BaCameraModel::kBalRadial, bal->cameras[static_cast<size_t>(o.camera)],
                                 bal->points[static_cast<size_t>(o.point)].p_world, o);
    EXPECT_NEAR(r.x(), -1.5, 1e-9);
    EXPECT_NEAR(r.y(), -0.5 * 500.0 / 480.0, 1e-9);
  }
}

TEST(BalFormat, WriteRefusesOutOfRangeObservation) {
  BaProblem pb;
  pb.cameras.resize(1);
  pb.points.resize(1);
  BaObservation o;
  o.point = 2;
  pb.observations.push_back(o);
  const auto st = write_bal(pb, (scratch_dir("bal_bad_write") / "x.txt").string());
  EXPECT_FALSE(st.ok());
}

}  // namespace
}  // namespace hwr::estimation
