// fit_T_enu_world (estimation/gnss_alignment.hpp): the world frame's yaw and position in ENU from
// GNSS fixes along the track. Oracles: a known T_enu_world, the closed-form yaw sigma.

#include <cmath>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "hwr/estimation/gnss_alignment.hpp"

namespace hwr::estimation {
namespace {

Eigen::Isometry3d T_enu_world_of(double yaw, const Eigen::Vector3d& t) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  T.translation() = t;
  return T;
}

// An L-shaped walk: 20 m along world x, then 10 m along world y, a fix every 0.5 m.
std::vector<Eigen::Vector3d> walk_world() {
  std::vector<Eigen::Vector3d> p;
  for (int i = 0; i <= 40; ++i) p.emplace_back(0.5 * i, 0.0, 1.2 + 0.01 * i);
  for (int i = 1; i <= 20; ++i) p.emplace_back(20.0, 0.5 * i, 1.6);
  return p;
}

TEST(GnssAlignment, GivenNoiseFreeFixesThenTheTransformIsExact) {
  const std::vector<Eigen::Vector3d> w = walk_world();
  for (double yaw : {-3.0, -1.2, 0.0, 0.7, 2.9}) {
    const Eigen::Isometry3d T = T_enu_world_of(yaw, Eigen::Vector3d(-35.2, 120.4, 3.3));
    std::vector<Eigen::Vector3d> e;
    for (const auto& p : w) e.push_back(T * p);
    const GnssAlignment a = fit_T_enu_world(w, e, 1.0, 2.0, NAN);
    ASSERT_TRUE(a.valid) << a.reason;
    EXPECT_NEAR(std::remainder(a.yaw_rad - yaw, 2 * M_PI), 0.0, 1e-12);
    EXPECT_LT((a.T_enu_world.translation() - T.translation()).norm(), 1e-9);
    EXPECT_LT(a.rms_horizontal_m, 1e-9);
    EXPECT_EQ(a.pairs_used, static_cast<int>(w.size()));
  }
}

// With 1 m fixes the yaw error stays within its predicted sigma (3 sigma over 200 trials, and the
// RMS normalised error near 1); outliers 30 m off are dropped.
TEST(GnssAlignment, GivenNoisyFixesAndOutliersThenTheErrorMatchesItsSigma) {
  const std::vector<Eigen::Vector3d> w = walk_world();
  const Eigen::Isometry3d T = T_enu_world_of(0.9, Eigen::Vector3d(10.0, -4.0, 0.5));
  std::mt19937 rng(5);
  std::normal_distribution<double> n(0.0, 1.0);
  double sum_z2 = 0;
  const int trials = 200;
  for (int trial = 0; trial < trials; ++trial) {
    std::vector<Eigen::Vector3d> e;
    for (const auto& p : w) e.push_back(T * p + Eigen::Vector3d(n(rng), n(rng), 2.0 * n(rng)));
    e[7].x() += 30.0;  // multipath
    e[33].y() -= 25.0;
    const GnssAlignment a = fit_T_enu_world(w, e, 1.0, 2.0, NAN);
    ASSERT_TRUE(a.valid) << a.reason;
    // The two outliers, and at most a rare 4-sigma draw of the 59 good fixes besides.
    EXPECT_GE(a.pairs_dropped, 2);
    EXPECT_LE(a.pairs_dropped, 4);
    EXPECT_LT(a.rms_horizontal_m, 2.0);
    const double err = std::remainder(a.yaw_rad - 0.9, 2 * M_PI);
    EXPECT_LT(std::abs(err), 3.5 * a.yaw_sigma_rad + 1e-3);
    sum_z2 += (err / a.yaw_sigma_rad) * (err / a.yaw_sigma_rad);
  }
  const double rms_z = std::sqrt(sum_z2 / trials);
  std::printf("[ gnss ] yaw sigma %.3f deg on the 30 m L walk, normalised RMS error %.2f\n",
              fit_T_enu_world(
                  w,
                  [&] {
                    std::vector<Eigen::Vector3d> e;
                    for (const auto& p : w) e.push_back(T * p);
                    return e;
                  }(),
                  1.0, 2.0, NAN)
                      .yaw_sigma_rad *
                  180.0 / M_PI,
              rms_z);
  EXPECT_GT(rms_z, 0.7);
  EXPECT_LT(rms_z, 1.3);
}

// Standing still the track cannot fix the yaw: not valid, unless the magnetometer gives it.
TEST(GnssAlignment, GivenNoMotionThenOnlyAGivenYawMakesItValid) {
  std::vector<Eigen::Vector3d> w(20, Eigen::Vector3d(1.0, 2.0, 1.0));
  const Eigen::Isometry3d T = T_enu_world_of(-0.4, Eigen::Vector3d(5.0, 6.0, 7.0));
  std::vector<Eigen::Vector3d> e;
  for (const auto& p : w) e.push_back(T * p);
  const GnssAlignment free_yaw = fit_T_enu_world(w, e, 1.0, 2.0, NAN);
  EXPECT_FALSE(free_yaw.valid);
  EXPECT_NE(free_yaw.reason.find("not moved enough"), std::string::npos) << free_yaw.reason;
  const GnssAlignment given = fit_T_enu_world(w, e, 1.0, 2.0, -0.4);
  ASSERT_TRUE(given.valid) << given.reason;
  EXPECT_EQ(given.yaw_sigma_rad, 0.0);
  EXPECT_LT((given.T_enu_world.translation() - T.translation()).norm(), 1e-9);
}

TEST(GnssAlignment, GivenBadInputsThenNotValidWithAReason) {
  const std::vector<Eigen::Vector3d> w = walk_world();
  std::vector<Eigen::Vector3d> e = w;
  EXPECT_FALSE(fit_T_enu_world(w, std::vector<Eigen::Vector3d>(3), 1.0, 2.0, NAN).valid);
  EXPECT_FALSE(fit_T_enu_world(w, e, 0.0, 2.0, NAN).valid);
  EXPECT_FALSE(fit_T_enu_world(w, e, 1.0, NAN, NAN).valid);
  std::vector<Eigen::Vector3d> two(w.begin(), w.begin() + 2), two_e(e.begin(), e.begin() + 2);
  const GnssAlignment few = fit_T_enu_world(two, two_e, 1.0, 2.0, NAN);
  EXPECT_FALSE(few.valid);
  EXPECT_NE(few.reason.find("usable pairs"), std::string::npos) << few.reason;
  e[0].x() = NAN;  // dropped, not fatal
  const GnssAlignment a = fit_T_enu_world(w, e, 1.0, 2.0, NAN);
  ASSERT_TRUE(a.valid) << a.reason;
  EXPECT_EQ(a.pairs_used, static_cast<int>(w.size()) - 1);
}

}  // namespace
}  // namespace hwr::estimation
