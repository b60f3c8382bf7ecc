// IMU synthesis: integrating the noise-free samples reproduces the ground truth; the noise has the
// configured densities; biases random-walk at the configured rate; streams are seeded.

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "hwr/core/time.hpp"
#include "hwr/sim/imu_synth.hpp"
#include "hwr/sim/scenario.hpp"

namespace hwr::sim {
namespace {

Trajectory lab_trajectory() {
  auto s = builtin_scenario("lab");
  EXPECT_TRUE(s.ok());
  auto t = Trajectory::build(s->trajectory);
  EXPECT_TRUE(t.ok());
  return std::move(t.value());
}

// A robot standing still for `seconds` (the trajectory clamps past its end).
Trajectory standing_still() {
  TrajectorySpec spec;
  spec.waypoints.resize(2);
  spec.waypoints[1].xy_m = {1.0, 0.0};
  auto t = Trajectory::build(spec);
  EXPECT_TRUE(t.ok());
  return std::move(t.value());
}

struct NavState {
  Eigen::Quaterniond q;
  Eigen::Vector3d v, p;
};

struct NavDerivative {
  Eigen::Vector4d dq;  // (w, x, y, z)
  Eigen::Vector3d dv, dp;
};

// q' = q (x) (0, w) / 2, v' = R f + g, p' = v.
NavDerivative derivative(const NavState& s, const hal::ImuSample& m, const Eigen::Vector3d& g) {
  const Eigen::Quaterniond w(0.0, m.gyro_radps.x(), m.gyro_radps.y(), m.gyro_radps.z());
  const Eigen::Quaterniond qd = s.q * w;
  NavDerivative d;
  d.dq = 0.5 * Eigen::Vector4d(qd.w(), qd.x(), qd.y(), qd.z());
  d.dv = s.q.toRotationMatrix() * m.accel_mps2 + g;
  d.dp = s.v;
  return d;
}

NavState add(const NavState& s, const NavDerivative& d, double h) {
  NavState o;
  o.q = Eigen::Quaterniond(s.q.w() + h * d.dq[0], s.q.x() + h * d.dq[1], s.q.y() + h * d.dq[2],
                           s.q.z() + h * d.dq[3]);
  o.v = s.v + h * d.dv;
  o.p = s.p + h * d.dp;
  return o;
}

// Classic RK4 with step h = 2 / rate: the samples at t, t + h/2 and t + h come straight from the
// synthesizer (no interpolation), so the only error is RK4's O(h^4) truncation.
double integration_drift_m(const Trajectory& traj, double t_start_s, double seconds) {
  ImuSpec spec;
  spec.rate_hz = 400.0;
  spec.noise.enabled = false;
  const std::vector<ImuRecord> imu = synthesize_imu(traj, spec, 1, t_start_s + seconds, 0);
  const Eigen::Vector3d g(0, 0, -spec.gravity_mps2);
  const size_t k0 = static_cast<size_t>(std::llround(t_start_s * spec.rate_hz));
  const TrajectoryState s0 = traj.evaluate(core::ns_to_s(imu[k0].sample.t_ns));
  NavState s{Eigen::Quaterniond(s0.T_scene_imu.linear()), s0.v_scene_mps, s0.T_scene_imu.translation()};
  const double h = 2.0 / spec.rate_hz;
  double max_err = 0.0;
  for (size_t k = k0; k + 2 < imu.size(); k += 2) {
    const hal::ImuSample& m0 = imu[k].sample;
    const hal::ImuSample& m1 = imu[k + 1].sample;
    const hal::ImuSample& m2 = imu[k + 2].sample;
    const NavDerivative k1 = derivative(s, m0, g);
    const NavDerivative k2 = derivative(add(s, k1, h / 2), m1, g);
    const NavDerivative k3 = derivative(add(s, k2, h / 2), m1, g);
    const NavDerivative k4 = derivative(add(s, k3, h), m2, g);
    NavDerivative sum;
    sum.dq = (k1.dq + 2 * k2.dq + 2 * k3.dq + k4.dq) / 6.0;
    sum.dv = (k1.dv + 2 * k2.dv + 2 * k3.dv + k4.dv) / 6.0;
    sum.dp = (k1.dp + 2 * k2.dp + 2 * k3.dp + k4.dp) / 6.0;
    s = add(s, sum, h);
    s.q.normalize();
    const TrajectoryState truth = traj.evaluate(core::ns_to_s(m2.t_ns));
    max_err = std::max(max_err, (s.p - truth.T_scene_imu.translation()).norm());
  }
  return max_err;
}

TEST(ImuSynth, GivenNoiseFreeImuWhenIntegratedWithRk4For10sThenPositionDriftIsBelowOneMillimetre) {
  const Trajectory traj = lab_trajectory();
  // From the first stop into the walk, and a window with turns in place and a stop.
  const double drift_walk = integration_drift_m(traj, 1.0, 10.0);
  const double drift_turns = integration_drift_m(traj, traj.stops()[1].t_arrive_s - 4.0, 10.0);
  EXPECT_LT(drift_walk, 1e-3);
  EXPECT_LT(drift_turns, 1e-3);
  RecordProperty("drift_walk_m", std::to_string(drift_walk));
  RecordProperty("drift_turns_m", std::to_string(drift_turns));
  std::printf("IMU RK4 drift over 10 s: %.3g m (walk), %.3g m (turns)\n", drift_walk, drift_turns);
}

TEST(ImuSynth, GivenRestWhenNoiseFreeThenAccelerometerReadsPlusGravityAlongZ) {
  const Trajectory traj = lab_trajectory();
  const hal::ImuSample m = ideal_imu(traj.evaluate(0.5), 9.81);
  EXPECT_LT((m.accel_mps2 - Eigen::Vector3d(0, 0, 9.81)).norm(), 1e-12);
  EXPECT_EQ(m.gyro_radps.norm(), 0.0);
}

Eigen::Vector3d sample_std(const std::vector<Eigen::Vector3d>& x) {
  Eigen::Vector3d mean = Eigen::Vector3d::Zero(), var = Eigen::Vector3d::Zero();
  for (const auto& v : x) mean += v;
  mean /= static_cast<double>(x.size());
  for (const auto& v : x) var += (v - mean).cwiseAbs2();
  return (var / static_cast<double>(x.size() - 1)).cwiseSqrt();
}

TEST(ImuSynth, GivenDensitiesWhenSampledAtTwoRatesThenWhiteNoiseStdIsDensityTimesSqrtRate) {
  const Trajectory traj = lab_trajectory();
  for (double rate : {200.0, 100.0}) {
    ImuSpec spec;
    spec.rate_hz = rate;
    spec.noise.gyro_random_walk = 0.0;
    spec.noise.accel_random_walk = 0.0;
    spec.noise.gyro_bias_initial_radps.setZero();
    spec.noise.accel_bias_initial_mps2.setZero();
    const std::vector<ImuRecord> imu = synthesize_imu(traj, spec, 7, 100.0, 0);
    std::vector<Eigen::Vector3d> ng, na;
    for (const ImuRecord& r : imu) {
      const hal::ImuSample ideal = ideal_imu(traj.evaluate(core::ns_to_s(r.sample.t_ns)), spec.gravity_mps2);
      ng.push_back(r.sample.gyro_radps - ideal.gyro_radps);
      na.push_back(r.sample.accel_mps2 - ideal.accel_mps2);
    }
    ASSERT_GE(imu.size(), 10000u);
    const double sg = spec.noise.gyro_noise_density * std::sqrt(rate);
    const double sa = spec.noise.accel_noise_density * std::sqrt(rate);
    const Eigen::Vector3d std_g = sample_std(ng), std_a = sample_std(na);
    for (int i = 0; i < 3; ++i) {
      EXPECT_NEAR(std_g[i], sg, 0.05 * sg) << "rate " << rate << " axis " << i;
      EXPECT_NEAR(std_a[i], sa, 0.05 * sa) << "rate " << rate << " axis " << i;
    }
  }
}

TEST(ImuSynth, GivenRandomWalkWhenBiasDifferencesMeasuredOverLagsThenVarianceGrowsLinearly) {
  const Trajectory traj = standing_still();
  ImuSpec spec;
  spec.noise.gyro_noise_density = 0.0;
  spec.noise.accel_noise_density = 0.0;
  const std::vector<ImuRecord> imu = synthesize_imu(traj, spec, 3, 2000.0, 0);
  // With white noise off, measurement - ideal is exactly the reported bias.
  const hal::ImuSample ideal = ideal_imu(traj.evaluate(10.0), spec.gravity_mps2);
  EXPECT_LT((imu[2000].sample.gyro_radps - ideal.gyro_radps - imu[2000].gyro_bias_radps).norm(), 1e-15);
  EXPECT_EQ(imu[0].gyro_bias_radps, spec.noise.gyro_bias_initial_radps);
  EXPECT_EQ(imu[0].accel_bias_mps2, spec.noise.accel_bias_initial_mps2);
  // Var[b(t + T) - b(t)] = density^2 T, from non-overlapping windows (per axis, pooled).
  for (double lag_s : {0.05, 1.0, 10.0}) {
    const size_t lag = static_cast<size_t>(lag_s * spec.rate_hz);
    double sg = 0, sa = 0;
    size_t n = 0;
    for (size_t k = 0; k + lag < imu.size(); k += lag) {
      sg += (imu[k + lag].gyro_bias_radps - imu[k].gyro_bias_radps).squaredNorm();
      sa += (imu[k + lag].accel_bias_mps2 - imu[k].accel_bias_mps2).squaredNorm();
      n += 3;
    }
    const double expect_g = spec.noise.gyro_random_walk * spec.noise.gyro_random_walk * lag_s;
    const double expect_a = spec.noise.accel_random_walk * spec.noise.accel_random_walk * lag_s;
    // n >= 600 samples of a chi-square variance: 4 sigma is ~23 %.
    EXPECT_NEAR(sg / n, expect_g, 0.25 * expect_g) << "lag " << lag_s;
    EXPECT_NEAR(sa / n, expect_a, 0.25 * expect_a) << "lag " << lag_s;
  }
}

TEST(ImuSynth, GivenSeedsWhenSynthesizedThenSameSeedIsIdenticalAndOtherSeedDiffers) {
  const Trajectory traj = lab_trajectory();
  const ImuSpec spec;
  const auto a = synthesize_imu(traj, spec, 42, 5.0, 1000);
  const auto b = synthesize_imu(traj, spec, 42, 5.0, 1000);
  const auto c = synthesize_imu(traj, spec, 43, 5.0, 1000);
  ASSERT_EQ(a.size(), 1001u);
  size_t differ = 0;
  for (size_t k = 0; k < a.size(); ++k) {
    EXPECT_EQ(a[k].sample.t_ns, 1000 + static_cast<int64_t>(k) * 5'000'000);
    EXPECT_EQ(a[k].sample.gyro_radps, b[k].sample.gyro_radps);
    EXPECT_EQ(a[k].sample.accel_mps2, b[k].sample.accel_mps2);
    differ += (a[k].sample.accel_mps2 != c[k].sample.accel_mps2) ? 1 : 0;
  }
  EXPECT_EQ(differ, a.size());
  // A shorter run is a prefix of a longer one.
  const auto d = synthesize_imu(traj, spec, 42, 2.0, 1000);
  for (size_t k = 0; k < d.size(); ++k) EXPECT_EQ(d[k].sample.accel_mps2, a[k].sample.accel_mps2);
}

}  // namespace
}  // namespace hwr::sim
