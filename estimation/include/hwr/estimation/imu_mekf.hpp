#pragma once
// IMU state propagation with a multiplicative (error-state) extended Kalman filter, the paper's
// MEKF over S_t = [R T V b] (paper.md item 2). Formulation: Sola, "Quaternion kinematics for the
// error-state Kalman filter" (arXiv:1711.02508, 2017), cited as [Sola17]; the rotation error is
// the LOCAL (right, body-frame) one of [Sola17] sec. 5:
//
//   R_true = R * Exp(dtheta)      p_true = p + dp      v_true = v + dv
//   bg_true = bg + dbg            ba_true = ba + dba
//
// Error state x = [dtheta(3) dp(3) dv(3) dbg(3) dba(3)] (this order everywhere, also in the
// covariance). Measurement model ([Sola17] sec. 5.3.1):
//   gyro  = omega + bg + n_g          accel = R^T (a_world - g_world) + ba + n_a
// with g_world = (0, 0, -gravity). Noise parameters are continuous-time densities (Kalibr / EuRoC
// convention), so the per-step covariance is density^2 * dt.
//
// Mean propagation between two samples: the bias-corrected gyro and accel are taken linear in time
// between the previous and the current sample; rotation by the 4th-order Magnus expansion for a
// linear rate (mid-point rate plus the dt^2/12 w0 x w1 coning term), velocity and position by
// Simpson / RK4 quadrature of the world-frame specific force at t0, t0 + dt/2, t0 + dt. The very
// first sample after initialize() is held constant back to the state time.
//
// Covariance: P <- F P F^T + Q. F is the discrete transition of the local-error kinematics of
// [Sola17] sec. 5.3.3 / 5.4 (there to first order; sec. 7's global error is not used), integrated with the
// same quadrature as the mean (rotation block Exp(-dtheta), velocity/position blocks from the integrated
// specific force, second-order gyro-bias couplings); it matches numeric differentiation of the mean step to
// 2e-8 (test). Q from the densities, with the dt^2/2, dt^3/3 position terms of the exact
// white-noise discretisation. The product uses F's block sparsity.
//
// Updates: linear-in-the-error updates on a contiguous block of the error state (pose:
// [dtheta dp], zero velocity: [dv]); Mahalanobis gate; Joseph form, symmetrised; then the error is
// injected (rotation multiplicatively, R <- R Exp(dtheta)) and the reset Jacobian
// G = blockdiag(I - [dtheta/2]x, I, ...) is applied ([Sola17] sec. 6.2-6.3).
//
// Firmware rule: every per-sample call is allocation-free (fixed-size Eigen only).

#include <cstdint>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "hwr/estimation/nav_state.hpp"
#include "hwr/hal/imu_sample.hpp"

namespace hwr::estimation {

// Continuous-time densities (Kalibr / EuRoC convention). Defaults: MEMS IMU of the ZED 2i class.
struct ImuNoise {
  double gyro_noise_density = 2.4e-4;   // rad/s/sqrt(Hz)
  double accel_noise_density = 1.6e-3;  // m/s^2/sqrt(Hz)
  double gyro_random_walk = 2e-6;       // rad/s^2/sqrt(Hz)
  double accel_random_walk = 4e-5;      // m/s^3/sqrt(Hz)
  double gravity_mps2 = 9.81;
};

using Vector15d = Eigen::Matrix<double, 15, 1>;

// The error-state retraction of the filter: x [+] dx = (R Exp(dtheta), p + dp, v + dv, bg + dbg,
// ba + dba), and its inverse a [-] b = dx with a = b [+] dx (rotation part Log(R_b^T R_a)).
NavState nav_state_plus(const NavState& x, const Vector15d& dx);
Vector15d nav_state_minus(const NavState& a, const NavState& b);

// One propagation step of the mean from x0 (at x0.t_ns, where sample s0 was taken) to s1.t_ns,
// and the error-state transition F of that step (x1_true [-] x1 = F (x0_true [-] x0) to first
// order). The filter's propagate() is this plus the covariance; exposed for the numeric-Jacobian
// test and the bench. s1.t_ns must be > x0.t_ns.
void imu_propagation_step(const NavState& x0, const hal::ImuSample& s0, const hal::ImuSample& s1,
                          const Eigen::Vector3d& g_world, NavState* x1, Eigen::Matrix<double, 15, 15>* F);

class ImuMekf {
 public:
  using Cov15 = Eigen::Matrix<double, 15, 15>;
  using Matrix6d = Eigen::Matrix<double, 6, 6>;

  // Error-state block offsets.
  static constexpr int kTheta = 0;
  static constexpr int kPos = 3;
  static constexpr int kVel = 6;
  static constexpr int kBg = 9;
  static constexpr int kBa = 12;

  // chi-square 99.9 % quantiles used as the default gates.
  static constexpr double kChi2Gate6 = 22.46;
  static constexpr double kChi2Gate3 = 16.27;

  struct Counters {
    uint64_t propagated = 0;        // samples integrated (or accepted as the first hold sample)
    uint64_t rejected_samples = 0;  // non-finite, not after the state time, or before initialize()
    uint64_t updates = 0;           // measurement updates applied
    uint64_t gated_updates = 0;     // updates refused by the Mahalanobis gate
    uint64_t rejected_updates = 0;  // non-finite measurement / covariance, or not initialized
  };

  explicit ImuMekf(const ImuNoise& noise = {});

  // x0.R_world_imu must be a rotation; P0 is symmetrised. Clears the held sample (the next sample is
  // held constant back to x0.t_ns) but keeps the counters.
  void initialize(const NavState& x0, const Cov15& P0);
  bool initialized() const { return initialized_; }

  // Propagates the state to sample.t_ns. Returns false (and counts it; state unchanged) when the
  // sample has non-finite values, is not later than the state time (a sample exactly at the state
  // time is accepted once, right after initialize(), as the hold sample), or the filter is not
  // initialized.
  bool propagate(const hal::ImuSample& sample);

  // Pose measurement of T_world_imu (e.g. the visual front end composed with the extrinsics).
  // Residual r = [Log(R^T R_meas); p_meas - p] (local rotation error, consistent with the error
  // state), H = [I6 0]. cov_meas is 6x6 in [rot, pos] order: the rotation block is the covariance
  // of n in R_meas = R_true Exp(n), i.e. in IMU axes. Gate: r^T S^-1 r > chi2_gate -> returns
  // false, state and covariance unchanged (counted in gated_updates).
  bool update_pose(const Eigen::Isometry3d& T_world_imu_meas, const Matrix6d& cov_meas,
                   double chi2_gate = kChi2Gate6);

  // Zero-velocity update (when static): measurement v_world = 0 with sigma_mps per axis.
  bool update_zero_velocity(double sigma_mps, double chi2_gate = kChi2Gate3);

  const NavState& state() const { return x_; }
  const Cov15& covariance() const { return P_; }
  Counters counters() const { return counters_; }
  const ImuNoise& noise() const { return noise_; }

 private:
  // The generic update on error-state block [first, first + M): r = z - h(x), H = [0 I_M 0].
  template <int M>
  bool update_block(int first, const Eigen::Matrix<double, M, 1>& r, const Eigen::Matrix<double, M, M>& R,
                    double chi2_gate);
  void inject_and_reset(const Eigen::Matrix<double, 15, 1>& dx);
  // P <- F P F^T exploiting F's block structure (F from imu_propagation_step).
  void propagate_covariance(const Cov15& F, double dt);

  ImuNoise noise_;
  Eigen::Vector3d g_world_;
  bool initialized_ = false;
  bool have_last_sample_ = false;
  hal::ImuSample last_sample_;
  NavState x_;
  Cov15 P_ = Cov15::Zero();
  Counters counters_;
};

}  // namespace hwr::estimation
