#pragma once
// Synthetic GNSS receiver (outdoor scenarios), NAV-PVT-like fixes (hal/gnss_fix.hpp). The scene
// frame is the local ENU frame of a geodetic origin, so the antenna position
// p_scene = p_imu + R_scene_imu * antenna_imu_m converts to WGS-84 through core/geodetic.hpp.
// Position error per ENU axis = white + first-order Gauss-Markov (slowly correlated, as multipath
// and atmosphere make real fixes wander):
//   x_{k+1} = phi x_k + sigma_gm sqrt(1 - phi^2) w_k,  phi = exp(-dt / tau)   (stationary)
// with sigma_white^2 + sigma_gm^2 = sigma^2 (sigma_h for east and north each, sigma_v for up).
// Dropouts (configured intervals and random ones) give fix_type 0 rows with NaN position.

#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "hwr/core/geodetic.hpp"
#include "hwr/hal/gnss_fix.hpp"
#include "hwr/sim/trajectory.hpp"

namespace hwr::sim {

struct GnssDropout {
  double start_s = 0.0;  // run time
  double end_s = 0.0;
};

struct GnssSpec {
  bool enabled = false;
  double rate_hz = 5.0;
  core::Geodetic origin{47.3769, 8.5417, 408.0};    // WGS-84 position of the scene origin
  Eigen::Vector3d antenna_imu_m{-0.10, 0.0, 0.45};  // antenna in the IMU frame (on the head)
  bool noise_enabled = true;
  double sigma_h_m = 1.0;            // 1-sigma error of east and of north
  double sigma_v_m = 2.0;            // 1-sigma error of up
  double correlated_fraction = 0.7;  // share of the variance in the Gauss-Markov part
  double correlation_time_s = 60.0;
  std::vector<GnssDropout> dropouts;
  double random_dropouts_per_min = 0.5;  // Poisson rate of extra dropouts
  double random_dropout_min_s = 2.0;
  double random_dropout_max_s = 8.0;
  int num_sv_min = 8;
  int num_sv_max = 16;
};

// One fix together with its truth (for tests and evaluation).
struct GnssRecord {
  hal::GnssFix fix;
  Eigen::Vector3d antenna_scene_m = Eigen::Vector3d::Zero();  // true antenna position
  Eigen::Vector3d error_enu_m = Eigen::Vector3d::Zero();      // noise added (also during dropouts)
  bool dropout = false;
};

// The dropout intervals in effect over [0, duration_s]: the configured ones and the random ones
// (seeded, drawn in time order so a shorter run sees a prefix of a longer run's).
std::vector<GnssDropout> gnss_dropouts(const GnssSpec& spec, uint64_t seed, double duration_s);

// Samples at sample_offsets_ns(rate_hz, duration_s); t_ns = t0_ns + offset. Empty if disabled.
std::vector<GnssRecord> synthesize_gnss(const Trajectory& trajectory, const GnssSpec& spec, uint64_t seed,
                                        double duration_s, int64_t t0_ns);

}  // namespace hwr::sim
