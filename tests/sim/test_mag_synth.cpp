// Magnetometer synthesis: the dipole field against its closed form, exact yaw away from steel,
// disturbed yaw near a beam, white noise of the configured sigma.

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "hwr/core/time.hpp"
#include "hwr/sim/mag_synth.hpp"

namespace hwr::sim {
namespace {

// A walk along +x from x0 to x1 at y, with a 90 deg turn at the end so yaw changes.
Trajectory walk(double x0, double x1, double y) {
  TrajectorySpec spec;
  spec.waypoints.resize(4);
  spec.waypoints[0].xy_m = {x0, y};
  spec.waypoints[1].xy_m = {0.5 * (x0 + x1), y + 0.5};
  spec.waypoints[2].xy_m = {x1, y};
  spec.waypoints[3].xy_m = {x1 + 1.0, y + 3.0};
  auto t = Trajectory::build(spec);
  EXPECT_TRUE(t.ok());
  return std::move(t.value());
}

SceneSpec one_beam_scene() {
  SceneSpec s;
  IBeamSpec b;
  b.name = "beam";
  b.length_m = 4.0;
  b.T_scene_beam.translation() = Eigen::Vector3d(0.0, 0.0, 0.15);
  s.beams.push_back(b);
  return s;
}

// Tilt-compensated heading. In the level frame L of yaw psi the field (0, Bn, Bu) reads
// Rz(psi)^T B = (Bn sin psi, Bn cos psi, Bu), so psi = atan2(b_x, b_y). Levelling needs roll and
// pitch only: R_yaw^T R_scene_imu = R_tilt does not depend on the yaw used.
double mag_yaw(const Eigen::Vector3d& m_imu, const Eigen::Matrix3d& R_scene_imu) {
  const Eigen::Vector3d x = R_scene_imu.col(0);
  const Eigen::Matrix3d R_yaw =
      Eigen::AngleAxisd(std::atan2(x.y(), x.x()), Eigen::Vector3d::UnitZ()).toRotationMatrix();
  const Eigen::Vector3d level = R_yaw.transpose() * R_scene_imu * m_imu;
  return std::atan2(level.x(), level.y());
}

TEST(MagSynth, GivenOneDipoleWhenEvaluatedOnAxisAndEquatorThenMatchesClosedForm) {
  MagSpec spec;
  spec.earth_field_scene_uT.setZero();
  spec.disturbance.cutoff_begin_m = 10.0;
  spec.disturbance.cutoff_end_m = 20.0;
  const std::vector<MagDipole> d = {{Eigen::Vector3d(1, 2, 3), Eigen::Vector3d(0, 0, 0.5)}};
  const double r = 0.8;
  // On the axis: B = 2 m / r^3; on the equator: B = -m / r^3.
  const Eigen::Vector3d axial = magnetic_field_scene_uT(spec, d, Eigen::Vector3d(1, 2, 3 + r));
  const Eigen::Vector3d equatorial = magnetic_field_scene_uT(spec, d, Eigen::Vector3d(1 + r, 2, 3));
  EXPECT_LT((axial - Eigen::Vector3d(0, 0, 2 * 0.5 / (r * r * r))).norm(), 1e-12);
  EXPECT_LT((equatorial - Eigen::Vector3d(0, 0, -0.5 / (r * r * r))).norm(), 1e-12);
}

TEST(MagSynth, GivenNoiseFreeSensorFarFromSteelWhenYawComputedThenItEqualsTrueYaw) {
  MagSpec spec;
  spec.noise_enabled = false;
  const SceneSpec scene = one_beam_scene();
  const std::vector<MagDipole> dipoles = mag_dipoles_for_scene(scene, spec, 1);
  ASSERT_FALSE(dipoles.empty());
  const Trajectory traj = walk(10.0, 20.0, 5.0);  // > 3 m (cutoff_end_m) from every dipole
  const std::vector<hal::MagSample> mag = synthesize_mag(traj, spec, dipoles, 1, traj.duration_s(), 0);
  ASSERT_GT(mag.size(), 100u);
  double max_err = 0.0, yaw_span = 0.0;
  const double yaw0 = mag_yaw(mag[0].field_uT - spec.hard_iron_uT, traj.evaluate(0).T_scene_imu.linear());
  for (const hal::MagSample& m : mag) {
    const TrajectoryState st = traj.evaluate(core::ns_to_s(m.t_ns));
    const Eigen::Vector3d x = st.T_scene_imu.linear().col(0);
    const double yaw = mag_yaw(m.field_uT - spec.hard_iron_uT, st.T_scene_imu.linear());
    max_err = std::max(max_err, std::abs(std::remainder(yaw - std::atan2(x.y(), x.x()), 2 * M_PI)));
    yaw_span = std::max(yaw_span, std::abs(std::remainder(yaw - yaw0, 2 * M_PI)));
  }
  EXPECT_LT(max_err, 1e-9);
  EXPECT_GT(yaw_span, 1.0);  // the walk really turns
}

TEST(MagSynth, GivenWalkPastABeamWhenYawComputedThenErrorGrowsNearTheBeamAndVanishesFarAway) {
  MagSpec spec;
  spec.noise_enabled = false;
  const SceneSpec scene = one_beam_scene();
  const std::vector<MagDipole> dipoles = mag_dipoles_for_scene(scene, spec, 1);
  // Straight past the beam, 0.8 m beside its axis (IMU 1.2 m up, beam on the floor).
  TrajectorySpec ts;
  ts.waypoints.resize(2);
  ts.waypoints[0].xy_m = {-8.0, 0.8};
  ts.waypoints[1].xy_m = {8.0, 0.8};
  auto traj = Trajectory::build(ts);
  ASSERT_TRUE(traj.ok());
  double err_near = 0.0, err_far = 0.0;
  for (double t = 0; t < traj->duration_s(); t += 0.05) {
    const TrajectoryState st = traj->evaluate(t);
    const Eigen::Vector3d p = st.T_scene_imu.translation();
    const Eigen::Vector3d m = st.T_scene_imu.linear().transpose() * magnetic_field_scene_uT(spec, dipoles, p);
    const Eigen::Vector3d x = st.T_scene_imu.linear().col(0);
    const double err =
        std::abs(std::remainder(mag_yaw(m, st.T_scene_imu.linear()) - std::atan2(x.y(), x.x()), 2 * M_PI));
    if (std::abs(p.x()) < 2.0) err_near = std::max(err_near, err);
    if (std::abs(p.x()) > 6.0) err_far = std::max(err_far, err);
  }
  EXPECT_GT(err_near, 1.0 * M_PI / 180.0);  // at least a degree off next to the steel
  EXPECT_LT(err_far, 1e-9);                 // exactly the Earth field beyond the cutoff
}

TEST(MagSynth, GivenNoiseWhenSampledThenStdMatchesSigmaAndSeedsAreReproducible) {
  MagSpec spec;
  spec.disturbance.enabled = false;
  TrajectorySpec ts;
  ts.waypoints.resize(2);
  ts.waypoints[1].xy_m = {1.0, 0.0};
  auto traj = Trajectory::build(ts);
  ASSERT_TRUE(traj.ok());
  const auto a = synthesize_mag(*traj, spec, {}, 5, 400.0, 0);
  const auto b = synthesize_mag(*traj, spec, {}, 5, 400.0, 0);
  const auto c = synthesize_mag(*traj, spec, {}, 6, 400.0, 0);
  ASSERT_EQ(a.size(), 20001u);
  Eigen::Vector3d sum = Eigen::Vector3d::Zero(), sq = Eigen::Vector3d::Zero();
  for (size_t k = 0; k < a.size(); ++k) {
    const TrajectoryState st = traj->evaluate(core::ns_to_s(a[k].t_ns));
    const Eigen::Vector3d clean =
        st.T_scene_imu.linear().transpose() * spec.earth_field_scene_uT + spec.hard_iron_uT;
    const Eigen::Vector3d n = a[k].field_uT - clean;
    sum += n;
    sq += n.cwiseAbs2();
    EXPECT_EQ(a[k].field_uT, b[k].field_uT);
    EXPECT_NE(a[k].field_uT, c[k].field_uT);
  }
  const double N = static_cast<double>(a.size());
  for (int i = 0; i < 3; ++i) {
    const double sd = std::sqrt(sq[i] / N - (sum[i] / N) * (sum[i] / N));
    EXPECT_NEAR(sd, spec.noise_sigma_uT, 0.05 * spec.noise_sigma_uT);
  }
}

}  // namespace
}  // namespace hwr::sim
