#pragma once
// Synthetic magnetometer. The scene frame is ENU (x east, y north, z up), so the Earth field is a
// constant vector in it (default 20 uT north, 40 uT down: inclination ~63 deg, a mid-latitude
// field); its horizontal part makes yaw observable. Measured in the IMU frame:
//   m = R_scene_imu^T (B_earth + B_steel(p)) + hard_iron + n
// Steel near the sensor (I-beams, plates, steel boxes/containers) bends the field: each steel
// object is modelled as a chain of point dipoles along its longest axis, magnetised mostly along
// the Earth field (induced) with a seeded remanent part, B = (3 (m.r) r / |r|^2 - m) / |r|^3
// (moments in uT m^3, i.e. mu0/4pi already folded in). The perturbation is faded out smoothly
// between cutoff_begin_m and cutoff_end_m, so far from steel the field is exactly the Earth's.

#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "hwr/hal/mag_sample.hpp"
#include "hwr/sim/scene_spec.hpp"
#include "hwr/sim/trajectory.hpp"

namespace hwr::sim {

struct MagDisturbanceSpec {
  bool enabled = true;
  double moment_per_m_uT_m3 = 3.0;  // dipole moment per metre of steel length
  double spacing_m = 0.75;          // dipoles along a long object
  double min_distance_m = 0.25;     // field evaluated no closer than this (no singularity)
  double cutoff_begin_m = 1.5;      // full strength inside, zero beyond cutoff_end_m
  double cutoff_end_m = 3.0;
  double remanent_fraction = 0.3;  // share of the moment in a random (seeded) direction
};

struct MagSpec {
  bool enabled = true;
  double rate_hz = 50.0;
  Eigen::Vector3d earth_field_scene_uT{0.0, 20.0, -40.0};
  Eigen::Vector3d hard_iron_uT{1.5, -2.0, 0.8};  // constant offset in the sensor frame
  bool noise_enabled = true;
  double noise_sigma_uT = 0.3;  // white, per axis and sample
  MagDisturbanceSpec disturbance;
};

struct MagDipole {
  Eigen::Vector3d p_scene_m = Eigen::Vector3d::Zero();
  Eigen::Vector3d moment_uT_m3 = Eigen::Vector3d::Zero();
};

// Dipoles of the scene's steel: beams, weld plates, boxes of steel materials. Deterministic in
// seed. Empty when the disturbance is disabled.
std::vector<MagDipole> mag_dipoles_for_scene(const SceneSpec& scene, const MagSpec& spec, uint64_t seed);

// Earth field plus steel perturbation at a scene point.
Eigen::Vector3d magnetic_field_scene_uT(const MagSpec& spec, const std::vector<MagDipole>& dipoles,
                                        const Eigen::Vector3d& p_scene_m);

// Samples at sample_offsets_ns(rate_hz, duration_s); t_ns = t0_ns + offset. Empty if disabled.
std::vector<hal::MagSample> synthesize_mag(const Trajectory& trajectory, const MagSpec& spec,
                                           const std::vector<MagDipole>& dipoles, uint64_t seed,
                                           double duration_s, int64_t t0_ns);

}  // namespace hwr::sim
