#include "hwr/estimation/imu_mekf.hpp"

#include <cmath>

#include <Eigen/Cholesky>

#include "hwr/core/so3.hpp"
#include "hwr/core/time.hpp"

namespace hwr::estimation {
namespace {

bool all_finite(const hal::ImuSample& s) { return s.gyro_radps.allFinite() && s.accel_mps2.allFinite(); }

// Re-projects R onto SO(3) through the unit quaternion; removes the round-off that repeated
// products accumulate (1e-16 per step) before it can grow.
Eigen::Matrix3d renormalized(const Eigen::Matrix3d& R) {
  Eigen::Quaterniond q(R);
  q.normalize();
  return q.toRotationMatrix();
}

}  // namespace

NavState nav_state_plus(const NavState& x, const Vector15d& dx) {
  NavState y = x;
  y.R_world_imu = x.R_world_imu * core::so3_exp(dx.segment<3>(ImuMekf::kTheta));
  y.p_world_imu_m += dx.segment<3>(ImuMekf::kPos);
  y.v_world_mps += dx.segment<3>(ImuMekf::kVel);
  y.gyro_bias_radps += dx.segment<3>(ImuMekf::kBg);
  y.accel_bias_mps2 += dx.segment<3>(ImuMekf::kBa);
  return y;
}

Vector15d nav_state_minus(const NavState& a, const NavState& b) {
  Vector15d dx;
  dx.segment<3>(ImuMekf::kTheta) = core::so3_log(b.R_world_imu.transpose() * a.R_world_imu);
  dx.segment<3>(ImuMekf::kPos) = a.p_world_imu_m - b.p_world_imu_m;
  dx.segment<3>(ImuMekf::kVel) = a.v_world_mps - b.v_world_mps;
  dx.segment<3>(ImuMekf::kBg) = a.gyro_bias_radps - b.gyro_bias_radps;
  dx.segment<3>(ImuMekf::kBa) = a.accel_bias_mps2 - b.accel_bias_mps2;
  return dx;
}

void imu_propagation_step(const NavState& x0, const hal::ImuSample& s0, const hal::ImuSample& s1,
                          const Eigen::Vector3d& g_world, NavState* x1, Eigen::Matrix<double, 15, 15>* F) {
  using M = ImuMekf;
  const double dt = core::ns_to_s(s1.t_ns - x0.t_ns);
  // Bias-corrected rates and specific forces, linear in time over [t0, t0 + dt].
  const Eigen::Vector3d w0 = s0.gyro_radps - x0.gyro_bias_radps;
  const Eigen::Vector3d w1 = s1.gyro_radps - x0.gyro_bias_radps;
  const Eigen::Vector3d wm = 0.5 * (w0 + w1);
  const Eigen::Vector3d a0 = s0.accel_mps2 - x0.accel_bias_mps2;
  const Eigen::Vector3d a1 = s1.accel_mps2 - x0.accel_bias_mps2;
  const Eigen::Vector3d am = 0.5 * (a0 + a1);

  // Rotation increments by the 4th-order Magnus expansion for a linear rate: the integral of w
  // plus the coning term (1/2) int alpha x w = dt^2/12 w0 x w1 (Bortz equation).
  const double h = 0.5 * dt;
  const Eigen::Vector3d dtheta_half = 0.5 * (w0 + wm) * h + (h * h / 12.0) * w0.cross(wm);
  const Eigen::Vector3d dtheta = wm * dt + (dt * dt / 12.0) * w0.cross(w1);
  const Eigen::Matrix3d R0 = x0.R_world_imu;
  const Eigen::Matrix3d Rm = R0 * core::so3_exp(dtheta_half);
  const Eigen::Matrix3d dR = core::so3_exp(dtheta);
  const Eigen::Matrix3d R1 = R0 * dR;

  // World-frame specific force at t0, t0 + dt/2, t0 + dt; Simpson for the velocity increment and
  // the RK4 (Simpson on (dt - u) f(u)) double integral for the position.
  const Eigen::Vector3d f0 = R0 * a0;
  const Eigen::Vector3d fm = Rm * am;
  const Eigen::Vector3d f1 = R1 * a1;
  const Eigen::Vector3d dv_sf = (dt / 6.0) * (f0 + 4.0 * fm + f1);
  const Eigen::Vector3d dp_sf = (dt * dt / 6.0) * (f0 + 2.0 * fm);

  *x1 = x0;
  x1->t_ns = s1.t_ns;
  x1->R_world_imu = R1;
  x1->p_world_imu_m = x0.p_world_imu_m + x0.v_world_mps * dt + dp_sf + 0.5 * dt * dt * g_world;
  x1->v_world_mps = x0.v_world_mps + dv_sf + dt * g_world;

  // Discrete error-state transition for the local rotation error ([Sola17] sec. 5.3.3 continuous, sec. 5.4
  // discrete), with the integrals taken by the same quadrature as the mean:
  //  - d(dtheta)/dt = -[w]x dtheta - dbg: F_theta_theta = Exp(dtheta)^T, F_theta_bg = Jr(dtheta)
  //    d(dtheta)/d(bg) (= -Jr dt plus the coning term's derivative).
  //  - d(dv)/dt = -R [a]x dtheta - R dba = -[R a]x (R dtheta) - R dba, and R(t) dtheta(t) = R0
  //    dtheta0 + R(t) Jr d(theta(t))/d(bg) dbg along the step, so F_v_theta = -[dv_sf]x R0
  //    ([Sola17]: -R [a]x dt to first order), F_v_ba = -int R, F_v_bg = -int [R a]x R Jr
  //    d(theta)/d(bg) (Simpson); the position rows likewise, integrated twice.
  const Eigen::Matrix3d I3 = Eigen::Matrix3d::Identity();
  // Rotation error (world axes) per unit gyro-bias error at t0 + dt/2 and t0 + dt:
  // R(t) Jr(theta(t)) d(theta(t))/d(bg).
  const Eigen::Matrix3d F_theta_bg =
      core::so3_right_jacobian(dtheta) * (-dt * I3 + (dt * dt / 12.0) * core::hat(w1 - w0));
  const Eigen::Matrix3d G_half =
      Rm * core::so3_right_jacobian(dtheta_half) * (-h * I3 + (h * h / 12.0) * core::hat(wm - w0));
  const Eigen::Matrix3d G_end = R1 * F_theta_bg;
  F->setIdentity();
  F->block<3, 3>(M::kTheta, M::kTheta) = dR.transpose();
  F->block<3, 3>(M::kTheta, M::kBg) = F_theta_bg;
  F->block<3, 3>(M::kPos, M::kTheta) = -core::hat(dp_sf) * R0;
  F->block<3, 3>(M::kPos, M::kVel) = dt * I3;
  F->block<3, 3>(M::kPos, M::kBg) = -(dt * dt / 3.0) * core::hat(fm) * G_half;
  F->block<3, 3>(M::kPos, M::kBa) = -(dt * dt / 6.0) * (R0 + 2.0 * Rm);
  F->block<3, 3>(M::kVel, M::kTheta) = -core::hat(dv_sf) * R0;
  F->block<3, 3>(M::kVel, M::kBg) = -(dt / 6.0) * (4.0 * core::hat(fm) * G_half + core::hat(f1) * G_end);
  F->block<3, 3>(M::kVel, M::kBa) = -(dt / 6.0) * (R0 + 4.0 * Rm + R1);
}

ImuMekf::ImuMekf(const ImuNoise& noise) : noise_(noise), g_world_(0.0, 0.0, -noise.gravity_mps2) {}

void ImuMekf::initialize(const NavState& x0, const Cov15& P0) {
  x_ = x0;
  P_ = 0.5 * (P0 + P0.transpose());
  have_last_sample_ = false;
  initialized_ = true;
}

bool ImuMekf::propagate(const hal::ImuSample& sample) {
  if (!initialized_ || !all_finite(sample) || sample.t_ns < x_.t_ns ||
      (sample.t_ns == x_.t_ns && have_last_sample_)) {
    ++counters_.rejected_samples;
    return false;
  }
  if (sample.t_ns == x_.t_ns) {  // the first sample, exactly at the state time: hold it
    last_sample_ = sample;
    have_last_sample_ = true;
    ++counters_.propagated;
    return true;
  }
  // Zero-order hold back to the state time for the first sample after initialize().
  const hal::ImuSample& s0 = have_last_sample_ ? last_sample_ : sample;
  const double dt = core::ns_to_s(sample.t_ns - x_.t_ns);
  NavState x1;
  Cov15 F;
  imu_propagation_step(x_, s0, sample, g_world_, &x1, &F);

  // Process noise from the continuous densities: white noise integrated over dt gives
  // density^2 * dt ([Sola17] sec. 5.4.3 with sigma_discrete^2 = density^2 / dt); the accelerometer
  // noise also reaches the position (dt^2/2, dt^3/3 terms of the exact discretisation).
  const double qg = noise_.gyro_noise_density * noise_.gyro_noise_density * dt;
  const double qa = noise_.accel_noise_density * noise_.accel_noise_density * dt;
  const double qbg = noise_.gyro_random_walk * noise_.gyro_random_walk * dt;
  const double qba = noise_.accel_random_walk * noise_.accel_random_walk * dt;
  propagate_covariance(F, dt);
  const Eigen::Matrix3d I3 = Eigen::Matrix3d::Identity();
  P_.block<3, 3>(kTheta, kTheta) += qg * I3;
  P_.block<3, 3>(kPos, kPos) += (qa * dt * dt / 3.0) * I3;
  P_.block<3, 3>(kPos, kVel) += (qa * dt / 2.0) * I3;
  P_.block<3, 3>(kVel, kPos) += (qa * dt / 2.0) * I3;
  P_.block<3, 3>(kVel, kVel) += qa * I3;
  P_.block<3, 3>(kBg, kBg) += qbg * I3;
  P_.block<3, 3>(kBa, kBa) += qba * I3;
  P_ = 0.5 * (P_ + P_.transpose()).eval();

  if (counters_.propagated % 64 == 0) x1.R_world_imu = renormalized(x1.R_world_imu);
  x_ = x1;
  last_sample_ = sample;
  have_last_sample_ = true;
  ++counters_.propagated;
  return true;
}

void ImuMekf::propagate_covariance(const Cov15& F, double dt) {
  // P <- F P F^T using F's structure (identity except the theta, p, v rows' blocks on theta, v,
  // bg, ba): about a third of the dense 15x15 products' work.
  using Block3 = Eigen::Matrix3d;
  const Block3 F_tt = F.block<3, 3>(kTheta, kTheta), F_tbg = F.block<3, 3>(kTheta, kBg);
  const Block3 F_pt = F.block<3, 3>(kPos, kTheta), F_pbg = F.block<3, 3>(kPos, kBg);
  const Block3 F_pba = F.block<3, 3>(kPos, kBa);
  const Block3 F_vt = F.block<3, 3>(kVel, kTheta), F_vbg = F.block<3, 3>(kVel, kBg);
  const Block3 F_vba = F.block<3, 3>(kVel, kBa);
  // A = F P, row blocks.
  Cov15 A = P_;
  A.middleRows<3>(kTheta).noalias() = F_tt * P_.middleRows<3>(kTheta);
  A.middleRows<3>(kTheta).noalias() += F_tbg * P_.middleRows<3>(kBg);
  A.middleRows<3>(kPos) += dt * P_.middleRows<3>(kVel);
  A.middleRows<3>(kPos).noalias() += F_pt * P_.middleRows<3>(kTheta);
  A.middleRows<3>(kPos).noalias() += F_pbg * P_.middleRows<3>(kBg);
  A.middleRows<3>(kPos).noalias() += F_pba * P_.middleRows<3>(kBa);
  A.middleRows<3>(kVel).noalias() += F_vt * P_.middleRows<3>(kTheta);
  A.middleRows<3>(kVel).noalias() += F_vbg * P_.middleRows<3>(kBg);
  A.middleRows<3>(kVel).noalias() += F_vba * P_.middleRows<3>(kBa);
  // P = A F^T, column blocks.
  P_ = A;
  P_.middleCols<3>(kTheta).noalias() = A.middleCols<3>(kTheta) * F_tt.transpose();
  P_.middleCols<3>(kTheta).noalias() += A.middleCols<3>(kBg) * F_tbg.transpose();
  P_.middleCols<3>(kPos) += dt * A.middleCols<3>(kVel);
  P_.middleCols<3>(kPos).noalias() += A.middleCols<3>(kTheta) * F_pt.transpose();
  P_.middleCols<3>(kPos).noalias() += A.middleCols<3>(kBg) * F_pbg.transpose();
  P_.middleCols<3>(kPos).noalias() += A.middleCols<3>(kBa) * F_pba.transpose();
  P_.middleCols<3>(kVel).noalias() += A.middleCols<3>(kTheta) * F_vt.transpose();
  P_.middleCols<3>(kVel).noalias() += A.middleCols<3>(kBg) * F_vbg.transpose();
  P_.middleCols<3>(kVel).noalias() += A.middleCols<3>(kBa) * F_vba.transpose();
}

template <int M>
bool ImuMekf::update_block(int first, const Eigen::Matrix<double, M, 1>& r,
                           const Eigen::Matrix<double, M, M>& R, double chi2_gate) {
  using MatM = Eigen::Matrix<double, M, M>;
  if (!initialized_ || !r.allFinite() || !R.allFinite()) {
    ++counters_.rejected_updates;
    return false;
  }
  // H = [0 I_M 0] with I_M at columns [first, first + M): S = H P H^T + R, P H^T = P's columns.
  const MatM S = P_.template block<M, M>(first, first) + 0.5 * (R + R.transpose());
  const Eigen::LLT<MatM> llt(S);
  if (llt.info() != Eigen::Success) {
    ++counters_.rejected_updates;
    return false;
  }
  const double d2 = r.dot(llt.solve(r));  // squared Mahalanobis distance
  if (!(d2 <= chi2_gate)) {
    ++counters_.gated_updates;
    return false;
  }
  const Eigen::Matrix<double, 15, M> PHt = P_.template middleCols<M>(first);
  const Eigen::Matrix<double, 15, M> K = llt.solve(PHt.transpose()).transpose();
  const Vector15d dx = K * r;

  // Joseph form: P = (I - K H) P (I - K H)^T + K R K^T, valid for any gain, keeps P PSD.
  Cov15 A = Cov15::Identity();
  A.template middleCols<M>(first) -= K;
  Cov15 AP;
  AP.noalias() = A * P_;
  P_.noalias() = AP * A.transpose();
  P_.noalias() += K * R * K.transpose();
  P_ = 0.5 * (P_ + P_.transpose()).eval();

  inject_and_reset(dx);
  ++counters_.updates;
  return true;
}

void ImuMekf::inject_and_reset(const Vector15d& dx) {
  // Error injection ([Sola17] sec. 6.2): R <- R Exp(dtheta), the rest additive.
  const Eigen::Vector3d dtheta = dx.segment<3>(kTheta);
  x_.R_world_imu = renormalized(x_.R_world_imu * core::so3_exp(dtheta));
  x_.p_world_imu_m += dx.segment<3>(kPos);
  x_.v_world_mps += dx.segment<3>(kVel);
  x_.gyro_bias_radps += dx.segment<3>(kBg);
  x_.accel_bias_mps2 += dx.segment<3>(kBa);
  // Reset ([Sola17] sec. 6.3, local error): P <- G P G^T with G = I except
  // G_theta_theta = I - [dtheta / 2]x; only the rotation rows and columns change.
  const Eigen::Matrix3d G = Eigen::Matrix3d::Identity() - core::hat(0.5 * dtheta);
  const Eigen::Matrix<double, 3, 15> top = G * P_.topRows<3>();
  P_.topRows<3>() = top;
  const Eigen::Matrix<double, 15, 3> left = P_.leftCols<3>() * G.transpose();
  P_.leftCols<3>() = left;
  P_ = 0.5 * (P_ + P_.transpose()).eval();
}

bool ImuMekf::update_pose(const Eigen::Isometry3d& T_world_imu_meas, const Matrix6d& cov_meas,
                          double chi2_gate) {
  const Eigen::Matrix3d R_meas = T_world_imu_meas.linear();
  if (!R_meas.allFinite() || !T_world_imu_meas.translation().allFinite()) {
    ++counters_.rejected_updates;
    return false;
  }
  Eigen::Matrix<double, 6, 1> r;
  r.head<3>() = core::so3_log(x_.R_world_imu.transpose() * R_meas);
  r.tail<3>() = T_world_imu_meas.translation() - x_.p_world_imu_m;
  return update_block<6>(kTheta, r, cov_meas, chi2_gate);
}

bool ImuMekf::update_zero_velocity(double sigma_mps, double chi2_gate) {
  if (!(sigma_mps > 0.0) || !std::isfinite(sigma_mps)) {
    ++counters_.rejected_updates;
    return false;
  }
  const Eigen::Vector3d r = -x_.v_world_mps;
  const Eigen::Matrix3d R = Eigen::Matrix3d::Identity() * (sigma_mps * sigma_mps);
  return update_block<3>(kVel, r, R, chi2_gate);
}

}  // namespace hwr::estimation
