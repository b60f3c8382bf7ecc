// GNSS synthesis: fix errors in ENU have the configured sigmas and correlation, dropouts give
// fix_type 0 with NaN positions, noise-free fixes are exact, streams are seeded.

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "hwr/core/geodetic.hpp"
#include "hwr/core/time.hpp"
#include "hwr/sim/gnss_synth.hpp"
#include "hwr/sim/scenario.hpp"

namespace hwr::sim {
namespace {

Trajectory outdoor_trajectory() {
  auto s = builtin_scenario("outdoor");
  EXPECT_TRUE(s.ok());
  auto t = Trajectory::build(s->trajectory);
  EXPECT_TRUE(t.ok());
  return std::move(t.value());
}

GnssSpec quiet_spec() {
  GnssSpec g;
  g.enabled = true;
  g.random_dropouts_per_min = 0.0;
  return g;
}

// Error of each fix in the scene's ENU frame, recomputed from lat/lon/height (the oracle is the
// geodetic inverse, not the synthesizer's own record).
std::vector<Eigen::Vector3d> enu_errors(const std::vector<GnssRecord>& recs, const GnssSpec& spec) {
  std::vector<Eigen::Vector3d> out;
  for (const GnssRecord& r : recs) {
    if (r.fix.fix_type == 0) continue;
    const core::Geodetic g{r.fix.lat_deg, r.fix.lon_deg, r.fix.height_m};
    out.push_back(core::geodetic_to_enu(g, spec.origin) - r.antenna_scene_m);
  }
  return out;
}

TEST(GnssSynth, GivenNoNoiseWhenFixesConvertedBackThenAntennaPositionIsExact) {
  const Trajectory traj = outdoor_trajectory();
  GnssSpec spec = quiet_spec();
  spec.noise_enabled = false;
  const auto recs = synthesize_gnss(traj, spec, 1, traj.duration_s(), 0);
  ASSERT_GT(recs.size(), 1000u);
  for (const Eigen::Vector3d& e : enu_errors(recs, spec)) EXPECT_LT(e.norm(), 1e-6);
  // The antenna rides on the head: offset from the IMU by R * antenna_imu_m.
  const TrajectoryState st = traj.evaluate(100.0);
  const auto one = synthesize_gnss(traj, spec, 1, 100.0, 0).back();
  EXPECT_LT((one.antenna_scene_m - st.T_scene_imu * spec.antenna_imu_m).norm(), 1e-12);
}

TEST(GnssSynth, GivenWhiteNoiseOnlyWhenErrorsMeasuredThenStdMatchesSigmaHAndSigmaV) {
  const Trajectory traj = outdoor_trajectory();
  GnssSpec spec = quiet_spec();
  spec.correlated_fraction = 0.0;
  const auto errs = enu_errors(synthesize_gnss(traj, spec, 3, 4000.0, 0), spec);
  ASSERT_GE(errs.size(), 20000u);
  Eigen::Vector3d sq = Eigen::Vector3d::Zero();
  for (const auto& e : errs) sq += e.cwiseAbs2();
  const Eigen::Vector3d sd = (sq / static_cast<double>(errs.size())).cwiseSqrt();
  EXPECT_NEAR(sd.x(), spec.sigma_h_m, 0.05 * spec.sigma_h_m);
  EXPECT_NEAR(sd.y(), spec.sigma_h_m, 0.05 * spec.sigma_h_m);
  EXPECT_NEAR(sd.z(), spec.sigma_v_m, 0.05 * spec.sigma_v_m);
}

TEST(GnssSynth, GivenCorrelatedNoiseWhenErrorsMeasuredThenStdAndLagCorrelationMatchGaussMarkov) {
  const Trajectory traj = outdoor_trajectory();
  GnssSpec spec = quiet_spec();
  spec.correlated_fraction = 1.0;
  spec.correlation_time_s = 5.0;
  const auto errs = enu_errors(synthesize_gnss(traj, spec, 4, 20000.0, 0), spec);
  const size_t lag = static_cast<size_t>(spec.correlation_time_s * spec.rate_hz);
  double sq = 0, cross = 0;
  for (size_t k = 0; k + lag < errs.size(); ++k) {
    sq += errs[k].x() * errs[k].x();
    cross += errs[k].x() * errs[k + lag].x();
  }
  const double n = static_cast<double>(errs.size() - lag);
  EXPECT_NEAR(std::sqrt(sq / n), spec.sigma_h_m, 0.1 * spec.sigma_h_m);
  EXPECT_NEAR(cross / sq, std::exp(-1.0), 0.06);  // autocorrelation at lag tau is 1/e
}

TEST(GnssSynth, GivenDropoutsWhenSynthesizedThenFixTypeZeroWithNanInsideAndThreeDOutside) {
  const Trajectory traj = outdoor_trajectory();
  GnssSpec spec = quiet_spec();
  spec.dropouts = {{10.0, 14.0}};
  spec.random_dropouts_per_min = 2.0;
  const double duration = 300.0;
  const auto recs = synthesize_gnss(traj, spec, 9, duration, 0);
  const auto windows = gnss_dropouts(spec, 9, duration);
  ASSERT_GE(windows.size(), 3u);  // the configured one plus random ones (~10 expected)
  size_t in = 0, out = 0;
  for (const GnssRecord& r : recs) {
    const double t = core::ns_to_s(r.fix.t_ns);
    bool inside = false;
    for (const GnssDropout& d : windows) inside |= (t >= d.start_s && t < d.end_s);
    if (inside) {
      ++in;
      EXPECT_EQ(r.fix.fix_type, 0);
      EXPECT_TRUE(std::isnan(r.fix.lat_deg) && std::isnan(r.fix.lon_deg) && std::isnan(r.fix.height_m));
      EXPECT_LE(r.fix.num_sv, 3);
    } else {
      ++out;
      EXPECT_EQ(r.fix.fix_type, 3);
      EXPECT_TRUE(std::isfinite(r.fix.lat_deg));
      EXPECT_GE(r.fix.num_sv, spec.num_sv_min);
      EXPECT_LE(r.fix.num_sv, spec.num_sv_max);
      EXPECT_EQ(r.fix.h_acc_m, spec.sigma_h_m);
    }
  }
  EXPECT_GE(in, 20u);  // at least the configured 4 s at 5 Hz
  EXPECT_GT(out, in);
  // A shorter run sees the same dropouts, truncated.
  const auto early = gnss_dropouts(spec, 9, 100.0);
  for (size_t i = 0; i < early.size(); ++i) EXPECT_EQ(early[i].start_s, windows[i].start_s);
}

TEST(GnssSynth, GivenSeedsWhenSynthesizedThenSameSeedIsIdenticalAndOtherSeedDiffers) {
  const Trajectory traj = outdoor_trajectory();
  const GnssSpec spec = quiet_spec();
  const auto a = synthesize_gnss(traj, spec, 1, 60.0, 0);
  const auto b = synthesize_gnss(traj, spec, 1, 60.0, 0);
  const auto c = synthesize_gnss(traj, spec, 2, 60.0, 0);
  ASSERT_EQ(a.size(), 301u);
  for (size_t k = 0; k < a.size(); ++k) {
    EXPECT_EQ(a[k].fix.lat_deg, b[k].fix.lat_deg);
    EXPECT_EQ(a[k].fix.height_m, b[k].fix.height_m);
    EXPECT_NE(a[k].fix.lat_deg, c[k].fix.lat_deg);
  }
  GnssSpec off;
  EXPECT_TRUE(synthesize_gnss(traj, off, 1, 60.0, 0).empty());  // disabled by default (indoor)
}

}  // namespace
}  // namespace hwr::sim
