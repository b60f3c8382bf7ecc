#pragma once
// Sensor priors of a relocalization query (issue #6 item 2; paper sec. II-E: "the IMU magnetometer
// helps estimate relative angles theta_z. When GPS data is available, absolute coordinates are
// used"): the relative yaw of the two runs' world frames from their magnetometers, and the current
// camera's position in the prior frame from GNSS, for RelocalizationQuery (relocalizer.hpp).
//
// Frames (ARCHITECTURE.md): `prior` = the earlier run's world frame (its map store's "world"),
// `world` = the current run's; both gravity-aligned with their own yaw, R_enu_world = Rz(psi)
// (mag_heading.hpp); `enu` = the local East-North-Up frame of a geodetic origin (core/geodetic.hpp)
// -- the prior's first keyframe fix, used by both runs so that their ENU frames are the same.
//
// Prior map (prior_sensor_frames, once after PriorMap::open), from its keyframes' sensor tags
// (keyframe_sensor_tags.hpp):
//  - psi_prior: estimation::MagHeadingEstimator fed with every keyframe's magnetometer sample at
//    the keyframe's IMU pose T_prior_imu = T_prior_cam * T_imu_cam^-1 (place-weighted);
//  - T_enu_prior: estimation::fit_T_enu_world of the keyframes' antenna positions
//    p_prior_antenna = T_prior_imu * antenna_imu_m against their fixes in ENU; when the track alone
//    does not fix the yaw (a short or straight walk), the yaw is fixed to psi_prior (use_mag).
// Current run (CurrentSensorPriors, fed as samples arrive, then fill() per query):
//  - yaw prior (use_mag): estimation::relative_yaw_prior_current(psi_prior, psi_current), i.e.
//    yaw(R_prior_world) = psi_current - psi_prior, sigma = the two sigmas combined;
//  - position prior (use_gnss): with a current yaw (psi_current = psi_enu_prior + the relative mag yaw,
//    so that a declination error common to both runs cancels; or from the current GNSS track when it
//    fixes the yaw), T_enu_world of the current run is fitted from its fixes
//    (fit_T_enu_world with that yaw) and p_prior_cam = T_enu_prior^-1 * T_enu_world * p_world_cam.
//    Without a yaw (GNSS only over a few metres: the track does not fix it), the newest fix alone:
//    p_prior_cam = T_enu_prior^-1 * p_enu_newest, its height moved by the camera's height above the
//    antenna (yaw-free in gravity-aligned frames), the horizontal displacement d since that fix
//    unknown in direction and so added to the sigma.
//    Sigma (horizontal, 1-sigma): sqrt(sigma_h^2 + rms_prior^2 + (yaw lever)^2 [+ d^2]): sigma_h,
//    not sigma_h / sqrt(n), because GNSS errors are correlated over tens of seconds (the simulator's
//    Gauss-Markov part, gnss_synth.hpp) and a few seconds of fixes do not average them out;
//    rms_prior = the prior fit's horizontal residual RMS, which holds the prior map's own drift
//    against GNSS; the yaw lever = the yaw sigma times the camera's distance from the current fixes'
//    centroid.
// A prior whose data is missing or invalid is left unset, and fill() says why.
//
// Memory: CurrentSensorPriors allocates its buffers at construction; add_mag(), add_gnss() and
// reset() never allocate (the robot's inertial task calls them). fill() runs off the control loop
// and allocates (the fit's result, the returned description).

#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "hwr/core/geodetic.hpp"
#include "hwr/core/status.hpp"
#include "hwr/estimation/gnss_alignment.hpp"
#include "hwr/estimation/mag_heading.hpp"
#include "hwr/hal/gnss_fix.hpp"
#include "hwr/hal/mag_sample.hpp"
#include "hwr/recon/prior_map.hpp"
#include "hwr/recon/relocalizer.hpp"

namespace hwr::recon {

struct RelocalizationPriorsConfig {
  // 1-sigma accuracy of one GNSS fix: horizontal (east and north each) and vertical.
  double sigma_h_m = 1.0;
  double sigma_v_m = 2.0;
  // The GNSS antenna in the IMU frame (the same robot in both runs).
  Eigen::Vector3d antenna_imu_m = Eigen::Vector3d::Zero();
  estimation::MagHeadingConfig mag;
  estimation::GnssAlignmentConfig gnss;
  bool use_mag = true;      // false: no yaw prior from the magnetometer (and no magnetometer yaw in the fits)
  bool use_gnss = true;     // false: no position prior (nor GNSS yaw)
  int gnss_capacity = 600;  // current-run fixes kept (the newest; 2 min at 5 Hz)
};

// The prior map's frames, computed once after PriorMap::open.
struct PriorSensorFrames {
  bool mag_valid = false;
  estimation::MagHeadingResult mag;  // psi_prior (mag.yaw_enu_world_rad); mag.reason when not valid
  bool enu_valid = false;
  estimation::GnssAlignment enu;  // enu.T_enu_world = T_enu_prior; enu.reason when not valid
  bool enu_yaw_from_mag = false;  // the track did not fix the yaw: it is psi_prior
  core::Geodetic origin;          // the ENU origin: the first keyframe fix (valid with any fix)
  Eigen::Vector3d p_prior_antenna_centroid_m = Eigen::Vector3d::Zero();  // of the fitted fixes
  int keyframes = 0, keyframes_mag = 0, keyframes_gnss = 0;
  std::string summary;  // one line: keyframes with mag / GNSS, psi and its sigma, the fit
};

// T_imu_cam: the prior run's camera-IMU extrinsic (its store's, StoreMetadata::T_imu_cam). A wrong
// one turns the keyframes' magnetometer samples with the robot's heading; the heading estimator's
// majority rule then refuses a heading (mag.reason names T_imu_cam) instead of returning a wrong
// one. The summary ends with "mag - ENU psi" when both headings exist (the declination error; more
// points at a wrong T_imu_cam or a disturbed magnetometer).
// Errors (kInvalidArgument): T_imu_cam not rigid, sigmas not positive and finite, a non-finite
// antenna offset. A prior map without magnetometer or GNSS tags is no error: mag_valid / enu_valid
// are false and the results' reasons say why.
core::Expected<PriorSensorFrames> prior_sensor_frames(const PriorMap& prior,
                                                      const Eigen::Isometry3d& T_imu_cam,
                                                      const RelocalizationPriorsConfig& config);

// The current run's sensor data, kept for the priors of its relocalization queries.
class CurrentSensorPriors {
 public:
  // Invalid values (non-positive sigmas, capacity < 1) are clamped to the defaults; validate the
  // config with prior_sensor_frames first.
  explicit CurrentSensorPriors(const RelocalizationPriorsConfig& config);

  // A magnetometer sample (IMU frame) with the estimator's attitude at its time. Never allocates.
  void add_mag(const hal::MagSample& sample, const Eigen::Matrix3d& R_world_imu);
  // A GNSS fix with the estimator's antenna position at its time (T_world_imu * antenna_imu_m).
  // Only 3D fixes with finite values are kept; the oldest is dropped beyond gnss_capacity. Never
  // allocates.
  void add_gnss(const hal::GnssFix& fix, const Eigen::Vector3d& p_world_antenna_m);

  // Sets query->yaw_valid / yaw_prior_rad / yaw_sigma_rad and query->position for a query keyframe
  // at T_world_cam (see the header comment); clears them first, leaves each unset when its data is
  // missing or invalid or when use_mag / use_gnss is off. Returns one line: what was set and why not.
  std::string fill(const PriorSensorFrames& prior, const Eigen::Isometry3d& T_world_cam,
                   RelocalizationQuery* query) const;

  void reset();

  const RelocalizationPriorsConfig& config() const { return config_; }
  int gnss_fixes() const { return static_cast<int>(gnss_count_); }
  uint64_t gnss_rejected() const { return gnss_rejected_; }
  // The current run's psi (for diagnostics; allocation-free except the reason string).
  estimation::MagHeadingResult mag_result() const { return mag_.result(); }

 private:
  struct Fix {
    int64_t t_ns = 0;
    core::Geodetic geodetic;
    Eigen::Vector3d p_world_antenna_m = Eigen::Vector3d::Zero();
  };
  const Fix& fix_at(size_t i) const { return fixes_[(gnss_head_ + i) % fixes_.size()]; }

  RelocalizationPriorsConfig config_;
  estimation::MagHeadingEstimator mag_;
  std::vector<Fix> fixes_;  // ring, capacity gnss_capacity
  size_t gnss_head_ = 0, gnss_count_ = 0;
  uint64_t gnss_rejected_ = 0;
  // Scratch of fill(), sized at construction.
  mutable std::vector<Eigen::Vector3d> p_world_, p_enu_;
};

}  // namespace hwr::recon
