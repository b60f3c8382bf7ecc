#pragma once
// Walking trajectory of the humanoid's IMU in the scene frame (x east, y north, z up), analytic
// to second order: position, velocity and acceleration are continuous everywhere (C2), and every
// derivative is computed in closed form (no finite differences), so the synthetic IMU is exactly
// the derivative of the ground-truth pose.
//
// Construction (build()):
//  - The waypoints are cut into pieces at the stops (the first and last waypoints are always
//    stops). Each piece is a clamped cubic spline through its waypoints in the floor plane,
//    parameterised by chord length; its end tangents point along the approach/departure chords,
//    so at a stop the heading is the path tangent and is defined although the speed is zero.
//  - Along a piece the arc length s(t) follows a smooth trapezoid: the speed rises from 0 to the
//    cruise speed with a quintic smoothstep (speed, acceleration and jerk zero at both ends), cruises,
//    and falls symmetrically. Short pieces lower the peak speed at the same peak acceleration.
//  - At a stop the robot may turn in place (quintic yaw profile) to face `look_at` (a weld joint),
//    dwells, then turns to the departure heading.
//  - Heading = path tangent while walking. A walking bob rides on top: vertical oscillation at
//    step frequency and roll at stride frequency, both proportional to the speed, so they vanish
//    at stops.
// The IMU body frame is x forward, y left, z up; at rest it is level.

#include <cstddef>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "hwr/core/status.hpp"

namespace hwr::sim {

struct Waypoint {
  Eigen::Vector2d xy_m = Eigen::Vector2d::Zero();  // scene frame, on the floor
  // > 0: the robot stops here for this long (plus turning). The first and last waypoints are
  // always stops, even with 0.
  double dwell_s = 0.0;
  // At a stop: face this floor point during the dwell (the weld joint to inspect).
  bool has_look_at = false;
  Eigen::Vector2d look_at_xy_m = Eigen::Vector2d::Zero();
};

struct TrajectorySpec {
  std::vector<Waypoint> waypoints;
  double cruise_speed_mps = 0.8;   // humanoid walking speed 0.4-1.0 m/s
  double ramp_time_s = 1.5;        // 0 -> cruise speed (and back) at a stop; must be > 0
  double turn_rate_radps = 0.8;    // peak yaw rate of a turn in place
  double min_turn_time_s = 1.0;    // even small turns take this long (smooth ω)
  double imu_height_m = 1.2;       // IMU above the floor (humanoid chest)
  double bob_m_per_mps = 0.015;    // vertical bob amplitude per m/s of speed
  double roll_rad_per_mps = 0.02;  // roll sway amplitude per m/s of speed
  double step_length_m = 0.6;      // one step; the bob has one period per step, roll per stride
};

// The full kinematic state at one instant.
struct TrajectoryState {
  double t_s = 0.0;
  Eigen::Isometry3d T_scene_imu = Eigen::Isometry3d::Identity();
  Eigen::Vector3d v_scene_mps = Eigen::Vector3d::Zero();
  Eigen::Vector3d a_scene_mps2 = Eigen::Vector3d::Zero();
  Eigen::Vector3d omega_imu_radps = Eigen::Vector3d::Zero();  // body angular velocity, IMU frame
  double speed_mps = 0.0;                                     // along the floor path
  double distance_m = 0.0;                                    // floor path length walked so far
};

// One stop of the timeline.
struct TrajectoryStop {
  size_t waypoint_index = 0;
  Eigen::Vector2d xy_m = Eigen::Vector2d::Zero();
  double t_arrive_s = 0.0;     // speed reaches 0
  double t_depart_s = 0.0;     // speed leaves 0
  double t_dwell_begin_s = 0;  // facing look_at (or the path) without moving
  double t_dwell_end_s = 0;
  double dwell_yaw_rad = 0.0;  // heading during the dwell (x axis from east, counter-clockwise)
};

class Trajectory {
 public:
  // Errors (InvalidArgument, naming the waypoint): fewer than 2 waypoints, coincident
  // consecutive waypoints, non-positive speeds/times, non-finite values.
  static core::Expected<Trajectory> build(const TrajectorySpec& spec);

  // Clamped to [0, duration_s()]: before the start and after the end the robot stands still.
  TrajectoryState evaluate(double t_s) const;

  double duration_s() const { return duration_s_; }
  // Floor path length (the bob's vertical motion not included).
  double length_m() const { return length_m_; }
  const std::vector<TrajectoryStop>& stops() const { return stops_; }
  const TrajectorySpec& spec() const { return spec_; }

  // Internals, public only so the implementation file can name them.
  struct Span {  // S(tau) = c0 + c1 tau + c2 tau^2 + c3 tau^3, tau in [0, h]
    Eigen::Vector2d c0, c1, c2, c3;
    double h = 0.0;                 // chord length (parameter span)
    double s0 = 0.0;                // arc length at the span start, within the piece
    static constexpr int kSub = 8;  // quadrature subintervals
    double cum[kSub + 1] = {};      // arc length from the span start to each subinterval start
  };
  struct Piece {
    std::vector<Span> spans;
    double length_m = 0.0;
    double distance0_m = 0.0;  // path walked before this piece
    double v_peak_mps = 0.0, t_ramp_s = 0.0, t_cruise_s = 0.0;
  };
  struct Phase {
    enum class Kind { kWalk, kTurn, kDwell } kind = Kind::kDwell;
    double t0_s = 0.0, t1_s = 0.0;
    size_t piece = 0;                                // kWalk
    Eigen::Vector2d xy_m = Eigen::Vector2d::Zero();  // kTurn, kDwell
    double yaw0_rad = 0.0, dyaw_rad = 0.0;           // kTurn: yaw0 + dyaw * smoothstep; kDwell: yaw0
    double distance_m = 0.0;                         // kTurn, kDwell
  };

 private:
  TrajectorySpec spec_;
  std::vector<Piece> pieces_;
  std::vector<Phase> phases_;
  std::vector<TrajectoryStop> stops_;
  double duration_s_ = 0.0;
  double length_m_ = 0.0;
};

}  // namespace hwr::sim
