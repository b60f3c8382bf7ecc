// ImuMekf (estimation/imu_mekf.hpp) against the simulator's exact ground truth: noise-free
// propagation, the analytic transition matrix against numeric differentiation, tracking with
// noisy pose updates, bias convergence, covariance consistency (NEES), gating, bad input and the
// no-allocation rule.

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "hwr/core/alloc_counter.hpp"
#include "hwr/core/so3.hpp"
#include "hwr/core/time.hpp"
#include "hwr/estimation/imu_mekf.hpp"
#include "hwr/sim/imu_synth.hpp"
#include "hwr/sim/random.hpp"
#include "hwr/sim/scenario.hpp"
#include "hwr/sim/trajectory.hpp"
#include "hwr/sim/world_frame.hpp"

namespace hwr::estimation {
namespace {

constexpr int64_t kT0 = 1'700'000'000'000'000'000LL;

// The lab walk (2 s standing, then walking and turning) and its world frame.
struct SimWalk {
  sim::Trajectory trajectory;
  Eigen::Isometry3d T_world_scene = Eigen::Isometry3d::Identity();
  sim::ImuSpec imu_spec;

  NavState truth(int64_t t_ns, const Eigen::Vector3d& bg = Eigen::Vector3d::Zero(),
                 const Eigen::Vector3d& ba = Eigen::Vector3d::Zero()) const {
    const sim::TrajectoryState st = trajectory.evaluate(core::ns_to_s(t_ns - kT0));
    const Eigen::Isometry3d T = T_world_scene * st.T_scene_imu;
    NavState x;
    x.t_ns = t_ns;
    x.R_world_imu = T.linear();
    x.p_world_imu_m = T.translation();
    x.v_world_mps = T_world_scene.linear() * st.v_scene_mps;
    x.gyro_bias_radps = bg;
    x.accel_bias_mps2 = ba;
    return x;
  }
};

SimWalk lab_walk() {
  auto scenario = sim::builtin_scenario("lab");
  EXPECT_TRUE(scenario.ok()) << scenario.status().to_string();
  auto trajectory = sim::Trajectory::build(scenario->trajectory);
  EXPECT_TRUE(trajectory.ok()) << trajectory.status().to_string();
  SimWalk w{std::move(trajectory).value(), Eigen::Isometry3d::Identity(), scenario->imu};
  w.T_world_scene = sim::world_frame_from_first_imu_pose(w.trajectory.evaluate(0.0).T_scene_imu).inverse();
  return w;
}

// The filter's noise model matched to the simulator's IMU.
ImuNoise matched_noise(const sim::ImuSpec& spec) {
  ImuNoise n;
  n.gyro_noise_density = spec.noise.gyro_noise_density;
  n.accel_noise_density = spec.noise.accel_noise_density;
  n.gyro_random_walk = spec.noise.gyro_random_walk;
  n.accel_random_walk = spec.noise.accel_random_walk;
  n.gravity_mps2 = spec.gravity_mps2;
  return n;
}

ImuMekf::Cov15 diag_cov(double theta, double p, double v, double bg, double ba) {
  Eigen::Matrix<double, 15, 1> d;
  d << Eigen::Vector3d::Constant(theta * theta), Eigen::Vector3d::Constant(p * p),
      Eigen::Vector3d::Constant(v * v), Eigen::Vector3d::Constant(bg * bg),
      Eigen::Vector3d::Constant(ba * ba);
  return d.asDiagonal();
}

double rotation_error_rad(const Eigen::Matrix3d& R_a, const Eigen::Matrix3d& R_b) {
  return core::so3_log(R_a.transpose() * R_b).norm();
}

TEST(ImuMekf, NoiseFreePropagationReproducesGroundTruthOver10s) {
  // GIVEN ideal IMU samples of the lab walk (2 s standing, 8 s walking and turning)
  const SimWalk walk = lab_walk();
  sim::ImuSpec spec = walk.imu_spec;
  spec.noise.enabled = false;
  const std::vector<sim::ImuRecord> imu = sim::synthesize_imu(walk.trajectory, spec, 1, 10.0, kT0);
  ASSERT_EQ(imu.size(), 2001u);
  // WHEN the filter starts at the true state and only propagates
  ImuMekf mekf(matched_noise(spec));
  mekf.initialize(walk.truth(kT0), diag_cov(1e-3, 1e-3, 1e-3, 1e-4, 1e-3));
  double max_pos_err = 0.0, max_rot_err = 0.0, max_vel_err = 0.0;
  for (const sim::ImuRecord& r : imu) {
    ASSERT_TRUE(mekf.propagate(r.sample));
    const NavState gt = walk.truth(r.sample.t_ns);
    max_pos_err = std::max(max_pos_err, (mekf.state().p_world_imu_m - gt.p_world_imu_m).norm());
    max_vel_err = std::max(max_vel_err, (mekf.state().v_world_mps - gt.v_world_mps).norm());
    max_rot_err = std::max(max_rot_err, rotation_error_rad(mekf.state().R_world_imu, gt.R_world_imu));
  }
  // THEN the pose stays on the ground truth: <= 1 mm and 1e-4 rad over the whole 10 s
  const double walked = walk.trajectory.evaluate(10.0).distance_m;
  EXPECT_GT(walked, 4.0);  // the oracle covers real motion
  EXPECT_LE(max_pos_err, 1e-3);
  EXPECT_LE(max_rot_err, 1e-4);
  EXPECT_LE(max_vel_err, 1e-3);
  EXPECT_EQ(mekf.counters().propagated, imu.size());
  EXPECT_EQ(mekf.counters().rejected_samples, 0u);
  RecordProperty("max_pos_err_m", std::to_string(max_pos_err));
  RecordProperty("max_rot_err_rad", std::to_string(max_rot_err));
}

TEST(ImuMekf, TransitionMatrixMatchesNumericDifferentiation) {
  // GIVEN a state mid-walk with biases, and two noisy samples 5 ms apart with a large rotation
  // rate (so that every block of F is exercised)
  NavState x0;
  x0.t_ns = kT0;
  x0.R_world_imu = core::so3_exp(Eigen::Vector3d(0.3, -0.2, 1.1));
  x0.p_world_imu_m = Eigen::Vector3d(1.0, 2.0, 1.2);
  x0.v_world_mps = Eigen::Vector3d(0.7, -0.3, 0.05);
  x0.gyro_bias_radps = Eigen::Vector3d(0.01, -0.02, 0.005);
  x0.accel_bias_mps2 = Eigen::Vector3d(0.1, -0.05, 0.2);
  hal::ImuSample s0, s1;
  s0.t_ns = kT0;
  s0.gyro_radps = Eigen::Vector3d(1.5, -0.8, 2.0);
  s0.accel_mps2 = Eigen::Vector3d(1.0, 2.0, 9.0);
  s1.t_ns = kT0 + 5'000'000;
  s1.gyro_radps = Eigen::Vector3d(1.2, -0.5, 2.4);
  s1.accel_mps2 = Eigen::Vector3d(1.5, 1.2, 10.0);
  const Eigen::Vector3d g(0, 0, -9.81);
  NavState x1;
  ImuMekf::Cov15 F;
  imu_propagation_step(x0, s0, s1, g, &x1, &F);
  // WHEN each error-state direction is perturbed by +-eps and the mean propagated again
  ImuMekf::Cov15 F_num;
  const double eps = 1e-6;
  for (int i = 0; i < 15; ++i) {
    NavState xp, xm;
    ImuMekf::Cov15 unused;
    imu_propagation_step(nav_state_plus(x0, eps * Vector15d::Unit(i)), s0, s1, g, &xp, &unused);
    imu_propagation_step(nav_state_plus(x0, -eps * Vector15d::Unit(i)), s0, s1, g, &xm, &unused);
    F_num.col(i) = (nav_state_minus(xp, x1) - nav_state_minus(xm, x1)) / (2.0 * eps);
  }
  // THEN the analytic F agrees to well below its smallest non-trivial entries (~dt^3 |a| = 1e-6)
  EXPECT_LE((F - F_num).cwiseAbs().maxCoeff(), 2e-8) << "F:\n" << F << "\nnumeric:\n" << F_num;
}

// One noisy run: IMU noise and biases on, pose updates at 30 Hz from the ground truth.
struct TrackingResult {
  double pos_rms_m = 0;  // after the burn-in
  double rot_rms_rad = 0;
  double mean_nees = 0;  // 15-dof NEES averaged over the post-update epochs after burn-in
  Eigen::Vector3d bg_err_end = Eigen::Vector3d::Zero();  // estimate minus truth at the end
  Eigen::Vector3d bg_sigma_end = Eigen::Vector3d::Zero();
  ImuMekf::Counters counters{};
};

constexpr double kSigmaPos = 0.02;  // m, per axis
constexpr double kSigmaRot = 0.01;  // rad, per axis (IMU axes)

TrackingResult run_tracking(const SimWalk& walk, uint64_t seed, double duration_s, double burn_in_s) {
  const std::vector<sim::ImuRecord> imu =
      sim::synthesize_imu(walk.trajectory, walk.imu_spec, seed, duration_s, kT0);
  ImuMekf mekf(matched_noise(walk.imu_spec));
  // Start at the true pose with zero bias estimates; P0 covers the true biases (2e-3 rad/s,
  // 4e-2 m/s^2 at most).
  mekf.initialize(walk.truth(kT0), diag_cov(0.01, 0.02, 0.05, 0.005, 0.1));
  sim::Rng rng(sim::derive_seed(seed, sim::RandomStream::kGnss, 77));
  Eigen::Matrix<double, 6, 6> cov_meas = Eigen::Matrix<double, 6, 6>::Identity();
  cov_meas.topLeftCorner<3, 3>() *= kSigmaRot * kSigmaRot;
  cov_meas.bottomRightCorner<3, 3>() *= kSigmaPos * kSigmaPos;
  TrackingResult out;
  size_t n = 0, n_nees = 0;
  int64_t next_update_ns = kT0;
  for (const sim::ImuRecord& r : imu) {
    EXPECT_TRUE(mekf.propagate(r.sample));
    if (r.sample.t_ns < next_update_ns) continue;
    next_update_ns += 33'333'333;  // 30 Hz
    const NavState gt = walk.truth(r.sample.t_ns, r.gyro_bias_radps, r.accel_bias_mps2);
    Eigen::Isometry3d T_meas = gt.T_world_imu();
    T_meas.linear() = gt.R_world_imu * core::so3_exp(kSigmaRot * sim::normal3(&rng));
    T_meas.translation() += kSigmaPos * sim::normal3(&rng);
    mekf.update_pose(T_meas, cov_meas);  // gated ones are counted
    if (core::ns_to_s(r.sample.t_ns - kT0) < burn_in_s) continue;
    const Vector15d e = nav_state_minus(gt, mekf.state());
    out.pos_rms_m += e.segment<3>(ImuMekf::kPos).squaredNorm();
    out.rot_rms_rad += e.segment<3>(ImuMekf::kTheta).squaredNorm();
    ++n;
    out.mean_nees += e.dot(mekf.covariance().ldlt().solve(e));
    ++n_nees;
    out.bg_err_end = -e.segment<3>(ImuMekf::kBg);
    out.bg_sigma_end = mekf.covariance().diagonal().segment<3>(ImuMekf::kBg).cwiseSqrt();
  }
  out.pos_rms_m = std::sqrt(out.pos_rms_m / n);
  out.rot_rms_rad = std::sqrt(out.rot_rms_rad / n);
  out.mean_nees /= n_nees;
  out.counters = mekf.counters();
  return out;
}

TEST(ImuMekf, NoisyImuWithPoseUpdatesTracksGroundTruthAndConvergesGyroBias) {
  // GIVEN the lab walk with IMU noise, random-walk biases (initial bias (2, -1.5, 1) mrad/s) and
  // pose measurements at 30 Hz with 2 cm / 10 mrad noise per axis
  const SimWalk walk = lab_walk();
  // WHEN the filter tracks 30 s of it
  const TrackingResult r = run_tracking(walk, 11, 30.0, 3.0);
  // THEN the position error is well under the measurement noise (3-D RMS 3.5 cm), the rotation
  // error under the rotation noise, and the gyro bias converged to the true one within 3e-4 rad/s
  // (15 % of the initial bias; the 30-s random walk of the true bias alone is ~1e-4) and within
  // 3 sigma of the filter's own covariance
  const double meas_pos_rms = kSigmaPos * std::sqrt(3.0);
  RecordProperty("pos_rms_m", std::to_string(r.pos_rms_m));
  RecordProperty("rot_rms_rad", std::to_string(r.rot_rms_rad));
  RecordProperty("bg_err_end_radps", std::to_string(r.bg_err_end.cwiseAbs().maxCoeff()));
  RecordProperty("gated", std::to_string(r.counters.gated_updates));
  EXPECT_LT(r.pos_rms_m, 0.35 * meas_pos_rms) << r.pos_rms_m;
  EXPECT_LT(r.rot_rms_rad, 0.5 * kSigmaRot * std::sqrt(3.0)) << r.rot_rms_rad;
  for (int a = 0; a < 3; ++a) {
    EXPECT_LT(std::abs(r.bg_err_end[a]), 3e-4) << "axis " << a;
    EXPECT_LT(std::abs(r.bg_err_end[a]), 3.0 * r.bg_sigma_end[a]) << "axis " << a;
  }
  // (a 99.9 % gate refuses ~1 in 1000 consistent measurements)
  EXPECT_LE(r.counters.gated_updates, 5u);
  EXPECT_EQ(r.counters.updates + r.counters.gated_updates, 901u);
}

TEST(ImuMekf, CovarianceIsConsistentNeesWithinChi2Band) {
  // GIVEN 8 independent noisy runs of 15 s (different IMU and measurement noise seeds)
  const SimWalk walk = lab_walk();
  constexpr int kRuns = 8;
  double nees = 0.0;
  uint64_t gated = 0, updates = 0;
  for (int k = 0; k < kRuns; ++k) {
    const TrackingResult r = run_tracking(walk, 100 + k, 15.0, 2.0);
    nees += r.mean_nees;
    gated += r.counters.gated_updates;
    updates += r.counters.updates;
    RecordProperty("nees_run" + std::to_string(k), std::to_string(r.mean_nees));
  }
  // The 99.9 % gate refuses about 1 in 1000 measurements of a consistent filter.
  EXPECT_LE(gated, 3 * (gated + updates) / 1000 + 2);
  nees /= kRuns;
  // THEN the average 15-dof NEES lies in the two-sided 99 % band of chi2(15 * 8) / 8, i.e.
  // [11.4, 19.2] (Bar-Shalom, "Estimation with applications to tracking", sec. 5.4). Each run's
  // value is itself a time average, whose spread is smaller than one chi2(15) draw, so the band is
  // conservative for a consistent filter; an over- or under-confident filter leaves it.
  EXPECT_GT(nees, 11.4);
  EXPECT_LT(nees, 19.2);
  RecordProperty("mean_nees", std::to_string(nees));
}

TEST(ImuMekf, GateRejectsOneMetreOutlierAndLeavesStateUnchanged) {
  // GIVEN a filter that has tracked 5 s with pose updates
  const SimWalk walk = lab_walk();
  const std::vector<sim::ImuRecord> imu = sim::synthesize_imu(walk.trajectory, walk.imu_spec, 5, 5.0, kT0);
  ImuMekf mekf(matched_noise(walk.imu_spec));
  mekf.initialize(walk.truth(kT0), diag_cov(0.01, 0.02, 0.05, 0.005, 0.1));
  Eigen::Matrix<double, 6, 6> cov_meas = Eigen::Matrix<double, 6, 6>::Identity() * (0.02 * 0.02);
  for (size_t i = 0; i < imu.size(); ++i) {
    ASSERT_TRUE(mekf.propagate(imu[i].sample));
    if (i % 7 == 0) {
      ASSERT_TRUE(mekf.update_pose(walk.truth(imu[i].sample.t_ns).T_world_imu(), cov_meas));
    }
  }
  const NavState before = mekf.state();
  const ImuMekf::Cov15 P_before = mekf.covariance();
  // WHEN a measurement 1 m off arrives
  Eigen::Isometry3d T_outlier = walk.truth(imu.back().sample.t_ns).T_world_imu();
  T_outlier.translation() += Eigen::Vector3d(0.6, -0.8, 0.0);
  const uint64_t updates_before = mekf.counters().updates;
  // THEN it is gated out, counted, and nothing changed
  EXPECT_FALSE(mekf.update_pose(T_outlier, cov_meas));
  EXPECT_EQ(mekf.counters().gated_updates, 1u);
  EXPECT_EQ(mekf.counters().updates, updates_before);
  EXPECT_EQ(mekf.state().p_world_imu_m, before.p_world_imu_m);
  EXPECT_EQ(mekf.state().R_world_imu, before.R_world_imu);
  EXPECT_EQ(mekf.state().v_world_mps, before.v_world_mps);
  EXPECT_EQ(mekf.covariance(), P_before);
  // and the same measurement without the offset passes the same gate
  EXPECT_TRUE(mekf.update_pose(walk.truth(imu.back().sample.t_ns).T_world_imu(), cov_meas));
}

TEST(ImuMekf, NonFiniteAndOutOfOrderSamplesAreRejectedAndCounted) {
  ImuMekf mekf;
  hal::ImuSample s;
  s.t_ns = kT0;
  s.accel_mps2 = Eigen::Vector3d(0, 0, 9.81);
  // Not initialized yet.
  EXPECT_FALSE(mekf.propagate(s));
  EXPECT_EQ(mekf.counters().rejected_samples, 1u);

  NavState x0;
  x0.t_ns = kT0;
  mekf.initialize(x0, diag_cov(0.01, 0.01, 0.01, 1e-3, 1e-2));
  ASSERT_TRUE(mekf.propagate(s));  // the hold sample at the state time
  s.t_ns += 5'000'000;
  ASSERT_TRUE(mekf.propagate(s));
  const NavState before = mekf.state();
  const ImuMekf::Cov15 P_before = mekf.covariance();

  hal::ImuSample bad = s;
  bad.t_ns += 5'000'000;
  bad.gyro_radps.y() = std::numeric_limits<double>::quiet_NaN();
  EXPECT_FALSE(mekf.propagate(bad));
  bad.gyro_radps.y() = 0.0;
  bad.accel_mps2.x() = std::numeric_limits<double>::infinity();
  EXPECT_FALSE(mekf.propagate(bad));
  hal::ImuSample same_time = s;  // duplicate time stamp
  EXPECT_FALSE(mekf.propagate(same_time));
  hal::ImuSample older = s;
  older.t_ns -= 1'000'000;
  EXPECT_FALSE(mekf.propagate(older));

  EXPECT_EQ(mekf.counters().rejected_samples, 5u);
  EXPECT_EQ(mekf.counters().propagated, 2u);
  EXPECT_EQ(mekf.state().t_ns, before.t_ns);
  EXPECT_EQ(mekf.state().R_world_imu, before.R_world_imu);
  EXPECT_EQ(mekf.state().p_world_imu_m, before.p_world_imu_m);
  EXPECT_EQ(mekf.state().v_world_mps, before.v_world_mps);
  EXPECT_EQ(mekf.covariance(), P_before);

  // A non-finite pose measurement is refused too.
  Eigen::Isometry3d T_nan = Eigen::Isometry3d::Identity();
  T_nan.translation().x() = std::numeric_limits<double>::quiet_NaN();
  EXPECT_FALSE(mekf.update_pose(T_nan, Eigen::Matrix<double, 6, 6>::Identity()));
  EXPECT_EQ(mekf.counters().rejected_updates, 1u);
  EXPECT_EQ(mekf.covariance(), P_before);
}

TEST(ImuMekf, ZeroVelocityUpdatesHoldAStandingImuStill) {
  // GIVEN 2 s of a standing, noisy IMU (the lab walk's initial dwell) and an initial velocity
  // error of 5 cm/s
  const SimWalk walk = lab_walk();
  const std::vector<sim::ImuRecord> imu = sim::synthesize_imu(walk.trajectory, walk.imu_spec, 3, 1.9, kT0);
  NavState x0 = walk.truth(kT0);
  x0.v_world_mps = Eigen::Vector3d(0.05, -0.03, 0.0);
  ImuMekf with_zupt(matched_noise(walk.imu_spec)), without(matched_noise(walk.imu_spec));
  with_zupt.initialize(x0, diag_cov(0.01, 0.01, 0.1, 0.005, 0.1));
  without.initialize(x0, diag_cov(0.01, 0.01, 0.1, 0.005, 0.1));
  // WHEN one filter gets a zero-velocity update at every sample
  for (const sim::ImuRecord& r : imu) {
    ASSERT_TRUE(with_zupt.propagate(r.sample));
    ASSERT_TRUE(without.propagate(r.sample));
    ASSERT_TRUE(with_zupt.update_zero_velocity(0.01));
  }
  // THEN its velocity and position stay near zero motion, unlike the free-running one
  const Eigen::Vector3d p0 = x0.p_world_imu_m;
  EXPECT_LT(with_zupt.state().v_world_mps.norm(), 0.01);
  EXPECT_LT((with_zupt.state().p_world_imu_m - p0).norm(), 0.03);
  EXPECT_GT((without.state().p_world_imu_m - p0).norm(), 0.05);
  EXPECT_LT(with_zupt.covariance().diagonal().segment<3>(ImuMekf::kVel).maxCoeff(),
            without.covariance().diagonal().segment<3>(ImuMekf::kVel).minCoeff());
}

TEST(ImuMekf, PropagateAndUpdatesAllocateNothing) {
  // GIVEN precomputed samples and measurements
  const SimWalk walk = lab_walk();
  const std::vector<sim::ImuRecord> imu = sim::synthesize_imu(walk.trajectory, walk.imu_spec, 9, 8.0, kT0);
  std::vector<Eigen::Isometry3d> meas(imu.size());
  for (size_t i = 0; i < imu.size(); ++i) meas[i] = walk.truth(imu[i].sample.t_ns).T_world_imu();
  const Eigen::Matrix<double, 6, 6> cov_meas = Eigen::Matrix<double, 6, 6>::Identity() * 4e-4;
  ImuMekf mekf(matched_noise(walk.imu_spec));
  mekf.initialize(walk.truth(kT0), diag_cov(0.01, 0.02, 0.05, 0.005, 0.1));
  // WHEN 1600 samples are propagated with a pose update every 7th and a zero-velocity update
  // (gated out while walking) every 50th
  uint64_t allocations = 0;
  size_t calls = 0;
  {
    core::AllocationScope scope;
    for (size_t i = 0; i < imu.size(); ++i) {
      calls += mekf.propagate(imu[i].sample) ? 1 : 0;
      if (i % 7 == 0) calls += mekf.update_pose(meas[i], cov_meas) ? 1 : 0;
      if (i % 50 == 0) calls += mekf.update_zero_velocity(0.05) ? 1 : 0;
    }
    allocations = scope.allocations();
  }
  // THEN nothing was allocated
  EXPECT_EQ(allocations, 0u);
  EXPECT_GE(calls, 1000u);
  EXPECT_EQ(mekf.counters().propagated, imu.size());
}

}  // namespace
}  // namespace hwr::estimation
