#pragma once
// IMU-rate pose history and pose interpolation to image timestamps (paper.md item 4).
//
// A fixed-capacity ring of NavStates (e.g. 4 s at 200 Hz = 800), filled by the inertial task after
// each propagation; the camera task asks for the pose at an image time:
//  - rotation on the SO(3) geodesic, R0 Exp(alpha Log(R0^T R1)) (core::so3_interpolate). The
//    paper's eq. (2) interpolates R linearly, which leaves SO(3) between the samples; the geodesic
//    is exact for a constant angular rate about a fixed axis.
//  - position by the cubic Hermite curve through p0, p1 with the states' velocities v0, v1 as end
//    tangents: exact for any motion whose position is a cubic polynomial in time (constant
//    velocity, constant acceleration, constant jerk), C1 across samples.
//  - velocity (interpolate_state only): linear between v0 and v1; biases: the older state's.
// Times outside [oldest, newest] are errors: too old -> kOutOfRange (evicted from the ring), too
// new -> kUnavailable (not propagated yet; may succeed later). An exact sample time returns that
// state. push() and the successful interpolate calls are allocation-free (only error Statuses
// carry a message string).

#include <cstddef>
#include <cstdint>
#include <vector>

#include <Eigen/Geometry>

#include "hwr/core/status.hpp"
#include "hwr/estimation/nav_state.hpp"

namespace hwr::estimation {

class PoseHistory {
 public:
  // capacity >= 2 (smaller values are raised to 2).
  explicit PoseHistory(size_t capacity);

  // Appends a state; when full the oldest is evicted. A state not strictly later than the newest
  // is refused (returns false, counted).
  bool push(const NavState& state);
  void clear();

  size_t size() const { return count_; }
  size_t capacity() const { return ring_.size(); }
  bool empty() const { return count_ == 0; }
  // i = 0 is the oldest kept state.
  const NavState& at(size_t i) const { return ring_[(head_ + i) % ring_.size()]; }
  const NavState& newest() const { return at(count_ - 1); }
  int64_t oldest_t_ns() const { return count_ ? at(0).t_ns : 0; }
  int64_t newest_t_ns() const { return count_ ? newest().t_ns : 0; }
  uint64_t refused_pushes() const { return refused_; }

  core::Status interpolate(int64_t t_ns, Eigen::Isometry3d* T_world_imu) const;
  // T_world_cam = T_world_imu(t) * T_imu_cam: the camera pose at an image time (paper.md item 4).
  core::Status interpolate_camera(int64_t t_ns, const Eigen::Isometry3d& T_imu_cam,
                                  Eigen::Isometry3d* T_world_cam) const;
  // The whole state at t_ns (R, p as above; v linear; biases of the older state).
  core::Status interpolate_state(int64_t t_ns, NavState* state) const;

 private:
  // Index i of the newest state with at(i).t_ns <= t_ns, or a range error.
  core::Status bracket(int64_t t_ns, size_t* i) const;

  std::vector<NavState> ring_;
  size_t head_ = 0;
  size_t count_ = 0;
  uint64_t refused_ = 0;
};

}  // namespace hwr::estimation
