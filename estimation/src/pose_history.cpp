#include "hwr/estimation/pose_history.hpp"

#include <algorithm>
#include <cstdio>

#include "hwr/core/so3.hpp"
#include "hwr/core/time.hpp"

namespace hwr::estimation {

PoseHistory::PoseHistory(size_t capacity) : ring_(std::max<size_t>(capacity, 2)) {}

bool PoseHistory::push(const NavState& state) {
  if (count_ > 0 && state.t_ns <= newest().t_ns) {
    ++refused_;
    return false;
  }
  if (count_ == ring_.size()) {
    head_ = (head_ + 1) % ring_.size();
    --count_;
  }
  ring_[(head_ + count_) % ring_.size()] = state;
  ++count_;
  return true;
}

void PoseHistory::clear() {
  head_ = 0;
  count_ = 0;
}

core::Status PoseHistory::bracket(int64_t t_ns, size_t* i) const {
  if (count_ == 0) return core::Unavailable("pose history: empty, no IMU state propagated yet");
  if (t_ns < oldest_t_ns()) {
    char buf[200];
    std::snprintf(buf, sizeof buf,
                  "pose history: t_ns=%lld is %.6f s older than the oldest kept state (evicted; the "
                  "history holds %.3f s)",
                  static_cast<long long>(t_ns), core::ns_to_s(oldest_t_ns() - t_ns),
                  core::ns_to_s(newest_t_ns() - oldest_t_ns()));
    return core::OutOfRange(buf);
  }
  if (t_ns > newest_t_ns()) {
    char buf[200];
    std::snprintf(buf, sizeof buf,
                  "pose history: t_ns=%lld is %.6f s newer than the newest propagated state (not yet "
                  "propagated)",
                  static_cast<long long>(t_ns), core::ns_to_s(t_ns - newest_t_ns()));
    return core::Unavailable(buf);
  }
  // Binary search for the last state with time <= t_ns.
  size_t lo = 0, hi = count_ - 1;
  while (lo < hi) {
    const size_t mid = (lo + hi + 1) / 2;
    if (at(mid).t_ns <= t_ns) {
      lo = mid;
    } else {
      hi = mid - 1;
    }
  }
  *i = lo;
  return core::Status::Ok();
}

core::Status PoseHistory::interpolate_state(int64_t t_ns, NavState* state) const {
  size_t i = 0;
  HWR_RETURN_IF_ERROR(bracket(t_ns, &i));
  const NavState& s0 = at(i);
  if (s0.t_ns == t_ns || i + 1 == count_) {
    *state = s0;
    return core::Status::Ok();
  }
  const NavState& s1 = at(i + 1);
  const double dt = core::ns_to_s(s1.t_ns - s0.t_ns);
  const double a = static_cast<double>(t_ns - s0.t_ns) / static_cast<double>(s1.t_ns - s0.t_ns);
  // Rotation on the SO(3) geodesic (replaces the paper's linear eq. 2).
  state->R_world_imu = core::so3_interpolate(s0.R_world_imu, s1.R_world_imu, a);
  // Cubic Hermite basis with the velocities as end tangents.
  const double a2 = a * a, a3 = a2 * a;
  const double h00 = 2.0 * a3 - 3.0 * a2 + 1.0;
  const double h10 = a3 - 2.0 * a2 + a;
  const double h01 = -2.0 * a3 + 3.0 * a2;
  const double h11 = a3 - a2;
  state->p_world_imu_m =
      h00 * s0.p_world_imu_m + h10 * dt * s0.v_world_mps + h01 * s1.p_world_imu_m + h11 * dt * s1.v_world_mps;
  state->v_world_mps = (1.0 - a) * s0.v_world_mps + a * s1.v_world_mps;
  state->gyro_bias_radps = s0.gyro_bias_radps;
  state->accel_bias_mps2 = s0.accel_bias_mps2;
  state->t_ns = t_ns;
  return core::Status::Ok();
}

core::Status PoseHistory::interpolate(int64_t t_ns, Eigen::Isometry3d* T_world_imu) const {
  NavState s;
  HWR_RETURN_IF_ERROR(interpolate_state(t_ns, &s));
  *T_world_imu = s.T_world_imu();
  return core::Status::Ok();
}

core::Status PoseHistory::interpolate_camera(int64_t t_ns, const Eigen::Isometry3d& T_imu_cam,
                                             Eigen::Isometry3d* T_world_cam) const {
  Eigen::Isometry3d T_world_imu;
  HWR_RETURN_IF_ERROR(interpolate(t_ns, &T_world_imu));
  *T_world_cam = T_world_imu * T_imu_cam;
  return core::Status::Ok();
}

}  // namespace hwr::estimation
