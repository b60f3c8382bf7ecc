#pragma once
// Magnetometer heading prior for relocalization (paper sec. II-E: "The IMU magnetometer helps
// estimate relative angles theta_z"; issue #6 item 2).
//
// Each run's world frame is gravity-aligned with an arbitrary yaw (ARCHITECTURE.md "Frames and
// names"). This estimates that yaw against ENU (x east, y north, z up; the simulator's scene
// frame): psi with R_enu_world = Rz(psi), i.e. psi is the ENU heading (from east,
// counter-clockwise) of the world x axis. Two runs then relate about the vertical by
// relative_yaw_prior_current().
//
// Per sample (add()): b_world = R_world_imu (m_imu - hard_iron), the field in the world frame;
// roll and pitch come from the estimator's gravity-aligned attitude, so this is the usual
// tilt-compensated compass. The undisturbed Earth field in ENU is
//   B_enu = (B_h sin D, B_h cos D, -B_h tan I)   (D declination east-positive, I dip down-positive)
// and b_world = Rz(psi)^T B_enu, so the horizontal angle of b_world is (pi/2 - D) - psi:
//   psi = wrap(pi/2 - D - atan2(b_world.y, b_world.x)).
// Hand check: D = +10 deg and b_world along world +y (magnetic north straight along world y):
// true north is 10 deg west (counter-clockwise) of world y, so world y points 10 deg east of
// north and psi = -10 deg.
//
// Disturbance rejection (result()): steel near the sensor (beams, plates, steel boxes; the
// simulator's dipoles, hal/sim mag_synth.hpp) bends the field. A sample is used only when
//  1. its horizontal field is at least min_horizontal_field_uT (else the heading is undefined),
//  2. | |b| - B_ref | <= field_tolerance_frac * B_ref,
//  3. | dip - I_ref | <= inclination_tolerance_rad, dip = atan2(-b_world.z, |b_world.xy|),
//  4. its heading lies within heading_gate_rad of the consensus heading. The consensus is seeded
//     by the heaviest heading_gate-wide window of a 1-degree weighted histogram (a mode, robust
//     to a disturbed minority on either side) and refined by re-gating around the weighted
//     circular mean until the set of used samples stops changing.
// B_ref and I_ref are the configured values, or else the weighted medians of all stored samples.
// Gates 2-3 miss a disturbance perpendicular to the horizontal field (it turns the heading but
// changes |b| and the dip only to second order); gate 4 and the place weighting catch it.
//
// Majority (result()): the used samples must carry at least min_used_fraction of the stored
// samples' weight (with positions: of the visited places), else there is no heading. This checks
// the premise below that most visited places are undisturbed, and it catches wrong attitudes: a
// wrong camera-IMU extrinsic (T_imu_cam) turns every sample by a rotation that moves with the
// robot's heading, so the field's dip and heading in the world frame sweep along the walk and only
// a minority of samples agrees. Measured (hwr-bench reloc, outdoor prior map whose store recorded
// an identity T_imu_cam instead of the simulator's camera mount): 167 of 1622 keyframe samples
// (10.7 % of the places) agreed on a heading 28.5 deg off the truth with a sigma of 0.57 deg;
// with the right mount all 1622 agree within 0.1 deg of the truth.
//
// Place weighting. Disturbance depends on where the sensor is, not for how long: a robot that
// dwells a minute at a weld station next to steel would otherwise outvote its whole walk (the
// time-weighted learned references and mode then lock onto the disturbed field). Samples given
// with a position (add(sample, T_world_imu)) are binned in place_cell_m cubes and each sample
// weighs 1 / (samples stored in its cube), so every visited place counts once. Samples given
// without a position (add(sample, R_world_imu)) share one place: with only those, all samples
// weigh the same (a stationary robot, or a caller without positions).
//
// Aggregate (weighted circular statistics): psi = arg(sum_k w_k u_k), u_k = (cos psi_k,
// sin psi_k); mean resultant length R = |sum w_k u_k| / sum w_k; effective sample count
// n_eff = (sum w)^2 / sum w^2 (Kish). The per-sample spread is
// s = max(sqrt(-2 ln R) (circular standard deviation), noise_sigma_uT / B_h), B_h the weighted
// mean horizontal field of the used samples (white noise of sigma per axis turns the horizontal
// vector by sigma / B_h rad); sigma_psi = sqrt(s^2 / n_eff + sigma_floor_rad^2). The floor stands
// for errors that do not average out: hard-iron residual, soft iron, attitude error, disturbances
// weak enough to pass the gates. The estimate is only as good as the premise that most visited
// places are undisturbed (or that B_ref and I_ref are configured, e.g. from a world magnetic
// model or from an earlier run's result()).
//
// Storage: samples are kept in a buffer of `capacity` records allocated at construction; add()
// never allocates. When the buffer is full it keeps every second record and from then on stores
// every second sample (stride doubles again at the next fill), so a long run stays uniformly
// represented. result() is O(capacity log capacity) on preallocated scratch: it is const but not
// safe against concurrent calls on the same object.

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "hwr/core/status.hpp"
#include "hwr/hal/mag_sample.hpp"

namespace hwr::estimation {

struct MagHeadingConfig {
  // Angle from true north to magnetic north, east-positive (WMM convention).
  double declination_rad = 0.0;
  // Hard-iron offset in the IMU frame (calibration), subtracted from every sample.
  Eigen::Vector3d hard_iron_imu_uT = Eigen::Vector3d::Zero();
  // |B| of the undisturbed field; 0: the weighted median |b| of the stored samples.
  double expected_field_uT = 0.0;
  double field_tolerance_frac = 0.1;
  // Dip of the undisturbed field, down-positive (northern hemisphere > 0); NaN: weighted median.
  double expected_inclination_rad = std::numeric_limits<double>::quiet_NaN();
  double inclination_tolerance_rad = 0.1;
  // White sensor noise per axis.
  double noise_sigma_uT = 0.3;
  // Samples with a weaker horizontal field carry no usable heading.
  double min_horizontal_field_uT = 1.0;
  // Consistency gate around the consensus heading (gate 4). Must exceed the per-sample noise
  // (noise_sigma / B_h) and the estimator's yaw drift over the samples.
  double heading_gate_rad = 10.0 * M_PI / 180.0;
  // Side of the place cubes of the weighting (values below 1 mm are raised to 1 mm).
  double place_cell_m = 0.5;
  // Fewer used samples than this: no heading.
  size_t min_samples = 20;
  // The used samples' share of the stored weight must reach this ("Majority"); 0 disables it.
  double min_used_fraction = 0.5;
  double sigma_floor_rad = 0.5 * M_PI / 180.0;
  // Records kept (see "Storage"); at least 2.
  size_t capacity = 8192;
};

struct MagHeadingResult {
  bool valid = false;
  std::string reason;  // why not valid; empty when valid
  // R_enu_world = Rz(yaw_enu_world_rad), in (-pi, pi]; 0 when not valid.
  double yaw_enu_world_rad = 0.0;
  double sigma_rad = 0.0;            // 1-sigma of yaw_enu_world_rad; 0 when not valid
  double resultant_length = 0.0;     // weighted mean resultant length R of the used headings
  double effective_samples = 0.0;    // n_eff of the used samples
  size_t places = 0;                 // distinct place cubes among the used samples
  double field_ref_uT = 0.0;         // B_ref of gate 2 (configured or learned)
  double inclination_ref_rad = 0.0;  // I_ref of gate 3
  double horizontal_field_uT = 0.0;  // weighted mean |b_world.xy| of the used samples
  // The used samples' share of the stored samples' weight ("Majority"; with positions: the share of
  // the visited places), in [0, 1]; set whenever samples are stored, valid or not.
  double used_fraction = 0.0;
  // Sample counts. seen = every add(); stored = kept in the buffer (decimation, "Storage").
  // stored = used + rejected_horizontal + rejected_field + rejected_inclination + rejected_heading.
  uint64_t seen = 0;
  uint64_t invalid_input = 0;  // non-finite field or pose, or an attitude that is not a rotation
  size_t stored = 0;
  size_t used = 0;
  size_t rejected_horizontal = 0;
  size_t rejected_field = 0;
  size_t rejected_inclination = 0;
  size_t rejected_heading = 0;
};

class MagHeadingEstimator {
 public:
  explicit MagHeadingEstimator(const MagHeadingConfig& config = {});

  // One sample: magnetometer reading (IMU frame) and the estimator's pose at its time (place
  // weighted). Allocation-free. A non-finite reading or pose, or an attitude that is not a
  // rotation, is counted and ignored.
  void add(const hal::MagSample& sample, const Eigen::Isometry3d& T_world_imu);
  // The same without a position: all such samples share one place.
  void add(const hal::MagSample& sample, const Eigen::Matrix3d& R_world_imu);
  void reset();

  // The world frame's yaw against ENU with its 1-sigma (header comment); valid = false with a
  // reason when too few samples, or too small a share of them (min_used_fraction), survive the
  // gates. Never NaN. used_per_stored, when given, is resized to `stored` and says which stored
  // records (in add() order, decimated as in "Storage") passed all four gates: a diagnostic, it
  // allocates.
  MagHeadingResult result(std::vector<bool>* used_per_stored = nullptr) const;

  const MagHeadingConfig& config() const { return config_; }

 private:
  struct Record {
    double yaw_enu_world_rad;  // psi implied by this sample alone
    double field_uT;           // |b|
    double inclination_rad;    // dip, down-positive
    double horizontal_uT;      // |b_world.xy|
    int64_t place;             // packed place cube; kNoPlace without a position
  };
  static constexpr int64_t kNoPlace = std::numeric_limits<int64_t>::min();

  void add_record(const hal::MagSample& sample, const Eigen::Matrix3d& R_world_imu, int64_t place);
  void compute_weights() const;
  double weighted_median(double Record::*field) const;

  MagHeadingConfig config_;
  std::vector<Record> records_;  // capacity fixed at construction
  size_t count_ = 0;
  uint64_t stride_ = 1;  // store every stride-th valid sample
  uint64_t seen_ = 0, valid_seen_ = 0, invalid_ = 0;
  // Scratch of result(), sized at construction.
  mutable std::vector<double> weight_;
  mutable std::vector<uint32_t> order_;
  mutable std::vector<std::pair<double, double>> value_weight_;
  mutable std::vector<uint8_t> gate_;
};

// Rotation about the vertical from the current run's world frame to the prior run's:
//   R_prior_current = R_enu_prior^T R_enu_current = Rz(psi_prior)^T Rz(psi_current)
//                   = Rz(psi_current - psi_prior),
// the yaw part of T_prior_current (hal/sim world_frame.hpp: T_prior_current =
// T_scene_world_prior^-1 T_scene_world_current with scene = ENU). Both runs must use the same
// declination (or each its correct one) and their own hard-iron calibration.
struct MagRelativeYaw {
  double yaw_prior_current_rad = 0.0;  // psi_current - psi_prior, wrapped to (-pi, pi]
  double sigma_rad = 0.0;              // sqrt(sigma_prior^2 + sigma_current^2)
  Eigen::Matrix3d R_prior_current = Eigen::Matrix3d::Identity();
};

// Unavailable naming the run ("prior" / "current") and its reason when either result is invalid.
core::Expected<MagRelativeYaw> relative_yaw_prior_current(const MagHeadingResult& prior,
                                                          const MagHeadingResult& current);

}  // namespace hwr::estimation
