#include "hwr/sim/trajectory.hpp"

#include <algorithm>
#include <cmath>
#include <string>

namespace hwr::sim {
namespace {

using Span = Trajectory::Span;
using Piece = Trajectory::Piece;
using Phase = Trajectory::Phase;

// Quintic smoothstep sigma(x) = 10x^3 - 15x^4 + 6x^5 and its derivatives and integral: value
// goes 0 -> 1 with first and second derivatives zero at both ends (minimum-jerk profile).
double smooth(double x) { return x * x * x * (10.0 + x * (-15.0 + 6.0 * x)); }
double smooth_d1(double x) { return 30.0 * x * x * (1.0 - x) * (1.0 - x); }
double smooth_d2(double x) { return 60.0 * x * (1.0 - x) * (1.0 - 2.0 * x); }
double smooth_integral(double x) { return x * x * x * x * (2.5 + x * (-3.0 + x)); }  // int_0^x sigma
// Peak of sigma' (at x = 1/2): a smoothstep over T reaching D has peak rate 1.875 D / T.
constexpr double kSmoothPeakRate = 1.875;

double wrap_pi(double a) {
  a = std::fmod(a + M_PI, 2.0 * M_PI);
  if (a < 0) a += 2.0 * M_PI;
  return a - M_PI;
}

// 8-point Gauss-Legendre on [-1, 1]: exact for polynomials of degree 15; |S'| is a smooth
// square root of a quartic, so 8 subintervals per span leave errors far below 1e-12 m.
constexpr double kGlX[4] = {0.1834346424956498, 0.5255324099163290, 0.7966664774136267, 0.9602898564975363};
constexpr double kGlW[4] = {0.3626837833783620, 0.3137066458778873, 0.2223810344533745, 0.1012285362903763};

Eigen::Vector2d d1(const Span& sp, double tau) { return sp.c1 + tau * (2.0 * sp.c2 + tau * 3.0 * sp.c3); }
Eigen::Vector2d d2(const Span& sp, double tau) { return 2.0 * sp.c2 + 6.0 * tau * sp.c3; }
Eigen::Vector2d pos(const Span& sp, double tau) {
  return sp.c0 + tau * (sp.c1 + tau * (sp.c2 + tau * sp.c3));
}

double arc_length(const Span& sp, double a, double b) {
  const double mid = 0.5 * (a + b), half = 0.5 * (b - a);
  double sum = 0.0;
  for (int k = 0; k < 4; ++k) {
    sum += kGlW[k] * (d1(sp, mid - half * kGlX[k]).norm() + d1(sp, mid + half * kGlX[k]).norm());
  }
  return sum * half;
}

// Clamped cubic spline through q with unit end tangents d0, dn, chord-length parameterised
// (de Boor, "A Practical Guide to Splines", ch. IV): solve the tridiagonal system for the second
// derivatives M_i, then convert each span to monomial coefficients.
std::vector<Span> clamped_spline(const std::vector<Eigen::Vector2d>& q, const Eigen::Vector2d& d0,
                                 const Eigen::Vector2d& dn) {
  const size_t n = q.size() - 1;
  std::vector<double> h(n);
  std::vector<Eigen::Vector2d> delta(n);
  for (size_t i = 0; i < n; ++i) {
    h[i] = (q[i + 1] - q[i]).norm();
    delta[i] = (q[i + 1] - q[i]) / h[i];
  }
  // Rows: a_i M_{i-1} + b_i M_i + c_i M_{i+1} = r_i.
  std::vector<double> a(n + 1, 0.0), b(n + 1, 0.0), c(n + 1, 0.0);
  std::vector<Eigen::Vector2d> r(n + 1);
  b[0] = 2.0 * h[0];
  c[0] = h[0];
  r[0] = 6.0 * (delta[0] - d0);
  for (size_t i = 1; i < n; ++i) {
    a[i] = h[i - 1];
    b[i] = 2.0 * (h[i - 1] + h[i]);
    c[i] = h[i];
    r[i] = 6.0 * (delta[i] - delta[i - 1]);
  }
  a[n] = h[n - 1];
  b[n] = 2.0 * h[n - 1];
  r[n] = 6.0 * (dn - delta[n - 1]);
  // Thomas algorithm (diagonally dominant, so stable without pivoting).
  for (size_t i = 1; i <= n; ++i) {
    const double m = a[i] / b[i - 1];
    b[i] -= m * c[i - 1];
    r[i] -= m * r[i - 1];
  }
  std::vector<Eigen::Vector2d> M(n + 1);
  M[n] = r[n] / b[n];
  for (size_t i = n; i-- > 0;) M[i] = (r[i] - c[i] * M[i + 1]) / b[i];

  std::vector<Span> spans(n);
  double s0 = 0.0;
  for (size_t i = 0; i < n; ++i) {
    Span& sp = spans[i];
    sp.h = h[i];
    sp.c0 = q[i];
    sp.c1 = delta[i] - h[i] * (2.0 * M[i] + M[i + 1]) / 6.0;
    sp.c2 = 0.5 * M[i];
    sp.c3 = (M[i + 1] - M[i]) / (6.0 * h[i]);
    sp.s0 = s0;
    const double dt = sp.h / Span::kSub;
    sp.cum[0] = 0.0;
    for (int j = 0; j < Span::kSub; ++j) sp.cum[j + 1] = sp.cum[j] + arc_length(sp, j * dt, (j + 1) * dt);
    s0 += sp.cum[Span::kSub];
  }
  return spans;
}

// Spline parameter tau within span `sp` at arc length s_in_span (Newton on s(tau) - s, started
// from linear interpolation inside the bracketing quadrature subinterval).
double invert_arc_length(const Span& sp, double s_in_span) {
  const double dt = sp.h / Span::kSub;
  int j = static_cast<int>(std::upper_bound(sp.cum, sp.cum + Span::kSub + 1, s_in_span) - sp.cum) - 1;
  j = std::clamp(j, 0, Span::kSub - 1);
  const double lo = j * dt, hi = (j + 1) * dt;
  const double seg = sp.cum[j + 1] - sp.cum[j];
  double tau = lo + (seg > 0 ? (s_in_span - sp.cum[j]) / seg : 0.0) * dt;
  tau = std::clamp(tau, lo, hi);
  for (int it = 0; it < 30; ++it) {
    const double f = sp.cum[j] + arc_length(sp, lo, tau) - s_in_span;
    const double step = f / d1(sp, tau).norm();
    tau = std::clamp(tau - step, lo, hi);
    if (std::abs(step) < 1e-14 * (1.0 + sp.h)) break;
  }
  return tau;
}

struct ArcState {
  double s = 0, sd = 0, sdd = 0, sddd = 0;  // arc length and its time derivatives
};

// Smooth trapezoid speed profile of one piece (see trajectory.hpp).
ArcState profile(const Piece& p, double tau) {
  const double tr = p.t_ramp_s, vp = p.v_peak_mps;
  const double total = 2.0 * tr + p.t_cruise_s;
  tau = std::clamp(tau, 0.0, total);
  ArcState a;
  if (tau < tr) {
    const double x = tau / tr;
    a.s = vp * tr * smooth_integral(x);
    a.sd = vp * smooth(x);
    a.sdd = vp * smooth_d1(x) / tr;
    a.sddd = vp * smooth_d2(x) / (tr * tr);
  } else if (tau <= tr + p.t_cruise_s) {
    a.s = 0.5 * vp * tr + vp * (tau - tr);
    a.sd = vp;
  } else {
    const double x = (total - tau) / tr;
    a.s = p.length_m - vp * tr * smooth_integral(x);
    a.sd = vp * smooth(x);
    a.sdd = -vp * smooth_d1(x) / tr;
    a.sddd = vp * smooth_d2(x) / (tr * tr);
  }
  return a;
}

bool finite2(const Eigen::Vector2d& v) { return std::isfinite(v.x()) && std::isfinite(v.y()); }

}  // namespace

core::Expected<Trajectory> Trajectory::build(const TrajectorySpec& spec) {
  const auto& wp = spec.waypoints;
  if (wp.size() < 2)
    return core::InvalidArgument("trajectory: needs at least 2 waypoints, got " + std::to_string(wp.size()));
  auto positive = [](double v) { return std::isfinite(v) && v > 0.0; };
  if (!positive(spec.cruise_speed_mps))
    return core::InvalidArgument("trajectory: cruise_speed_mps must be > 0");
  if (!positive(spec.ramp_time_s)) return core::InvalidArgument("trajectory: ramp_time_s must be > 0");
  if (!positive(spec.turn_rate_radps))
    return core::InvalidArgument("trajectory: turn_rate_radps must be > 0");
  if (!positive(spec.min_turn_time_s))
    return core::InvalidArgument("trajectory: min_turn_time_s must be > 0");
  if (!positive(spec.step_length_m)) return core::InvalidArgument("trajectory: step_length_m must be > 0");
  if (!std::isfinite(spec.imu_height_m) || !std::isfinite(spec.bob_m_per_mps) ||
      !std::isfinite(spec.roll_rad_per_mps)) {
    return core::InvalidArgument(
        "trajectory: imu_height_m, bob_m_per_mps and roll_rad_per_mps must be finite");
  }
  for (size_t i = 0; i < wp.size(); ++i) {
    const std::string who = "trajectory: waypoint " + std::to_string(i);
    if (!finite2(wp[i].xy_m) || !std::isfinite(wp[i].dwell_s) || wp[i].dwell_s < 0.0 ||
        !finite2(wp[i].look_at_xy_m)) {
      return core::InvalidArgument(who + ": values must be finite and dwell_s >= 0");
    }
    if (i > 0 && (wp[i].xy_m - wp[i - 1].xy_m).norm() < 1e-3) {
      return core::InvalidArgument(who + ": coincides with waypoint " + std::to_string(i - 1));
    }
    if (wp[i].has_look_at && (wp[i].look_at_xy_m - wp[i].xy_m).norm() < 1e-3) {
      return core::InvalidArgument(who + ": look_at coincides with the waypoint");
    }
  }

  Trajectory tr;
  tr.spec_ = spec;
  const size_t last = wp.size() - 1;
  std::vector<size_t> stop_idx;
  for (size_t i = 0; i <= last; ++i) {
    if (i == 0 || i == last || wp[i].dwell_s > 0.0) stop_idx.push_back(i);
  }
  auto chord = [&](size_t from, size_t to) -> Eigen::Vector2d {
    return (wp[to].xy_m - wp[from].xy_m).normalized();
  };
  // Arrival and departure tangents at each stop.
  std::vector<Eigen::Vector2d> arrive(stop_idx.size()), depart(stop_idx.size());
  for (size_t k = 0; k < stop_idx.size(); ++k) {
    const size_t w = stop_idx[k];
    if (w == 0) {
      depart[k] = chord(0, 1);
      arrive[k] = depart[k];
    } else if (w == last) {
      arrive[k] = chord(w - 1, w);
      depart[k] = arrive[k];
    } else if (wp[w].has_look_at) {
      arrive[k] = chord(w - 1, w);
      depart[k] = chord(w, w + 1);
    } else {
      // Pass straight through the stop: Catmull-Rom direction, no turn needed.
      Eigen::Vector2d d = wp[w + 1].xy_m - wp[w - 1].xy_m;
      if (d.norm() < 1e-6) d = wp[w].xy_m - wp[w - 1].xy_m;
      arrive[k] = depart[k] = d.normalized();
    }
  }
  // Pieces between consecutive stops.
  double distance = 0.0;
  for (size_t k = 0; k + 1 < stop_idx.size(); ++k) {
    std::vector<Eigen::Vector2d> q;
    for (size_t i = stop_idx[k]; i <= stop_idx[k + 1]; ++i) q.push_back(wp[i].xy_m);
    Piece p;
    p.spans = clamped_spline(q, depart[k], arrive[k + 1]);
    p.length_m = p.spans.back().s0 + p.spans.back().cum[Span::kSub];
    p.distance0_m = distance;
    const double v = spec.cruise_speed_mps, ramp = spec.ramp_time_s;
    if (p.length_m >= v * ramp) {
      p.v_peak_mps = v;
      p.t_ramp_s = ramp;
      p.t_cruise_s = (p.length_m - v * ramp) / v;
    } else {
      // Same peak acceleration (v / ramp) on a piece too short to reach cruise speed.
      p.t_ramp_s = std::sqrt(p.length_m * ramp / v);
      p.v_peak_mps = p.length_m / p.t_ramp_s;
      p.t_cruise_s = 0.0;
    }
    distance += p.length_m;
    tr.pieces_.push_back(std::move(p));
  }
  tr.length_m_ = distance;

  // Timeline.
  double t = 0.0;
  auto add_turn = [&](const Eigen::Vector2d& xy, double yaw0, double yaw1, double dist) {
    const double dyaw = wrap_pi(yaw1 - yaw0);
    if (std::abs(dyaw) < 1e-12) return;
    Phase ph;
    ph.kind = Phase::Kind::kTurn;
    ph.t0_s = t;
    ph.t1_s = t + std::max(spec.min_turn_time_s, kSmoothPeakRate * std::abs(dyaw) / spec.turn_rate_radps);
    ph.xy_m = xy;
    ph.yaw0_rad = yaw0;
    ph.dyaw_rad = dyaw;
    ph.distance_m = dist;
    tr.phases_.push_back(ph);
    t = ph.t1_s;
  };
  auto angle = [](const Eigen::Vector2d& d) { return std::atan2(d.y(), d.x()); };
  for (size_t k = 0; k < stop_idx.size(); ++k) {
    const size_t w = stop_idx[k];
    const Eigen::Vector2d xy = wp[w].xy_m;
    const double dist = k == 0 ? 0.0 : tr.pieces_[k - 1].distance0_m + tr.pieces_[k - 1].length_m;
    const double yaw_depart = angle(depart[k]);
    const double yaw_look = wp[w].has_look_at ? angle(wp[w].look_at_xy_m - xy) : angle(arrive[k]);
    // The run starts already facing the look_at target (no arrival turn).
    const double yaw_arrive = (k == 0) ? yaw_look : angle(arrive[k]);
    TrajectoryStop stop;
    stop.waypoint_index = w;
    stop.xy_m = xy;
    stop.t_arrive_s = t;
    add_turn(xy, yaw_arrive, yaw_look, dist);
    stop.t_dwell_begin_s = t;
    stop.dwell_yaw_rad = yaw_look;
    if (wp[w].dwell_s > 0.0) {
      Phase ph;
      ph.kind = Phase::Kind::kDwell;
      ph.t0_s = t;
      ph.t1_s = t + wp[w].dwell_s;
      ph.xy_m = xy;
      ph.yaw0_rad = yaw_look;
      ph.distance_m = dist;
      tr.phases_.push_back(ph);
      t = ph.t1_s;
    }
    stop.t_dwell_end_s = t;
    if (w != last) add_turn(xy, yaw_look, yaw_depart, dist);
    stop.t_depart_s = t;
    tr.stops_.push_back(stop);
    if (k < tr.pieces_.size()) {
      const Piece& p = tr.pieces_[k];
      Phase ph;
      ph.kind = Phase::Kind::kWalk;
      ph.t0_s = t;
      ph.t1_s = t + 2.0 * p.t_ramp_s + p.t_cruise_s;
      ph.piece = k;
      tr.phases_.push_back(ph);
      t = ph.t1_s;
    }
  }
  tr.duration_s_ = t;
  return tr;
}

TrajectoryState Trajectory::evaluate(double t_s) const {
  TrajectoryState st;
  st.t_s = t_s;
  const double t = std::clamp(t_s, 0.0, duration_s_);
  // Last phase starting at or before t.
  auto it = std::upper_bound(phases_.begin(), phases_.end(), t,
                             [](double x, const Phase& p) { return x < p.t0_s; });
  const Phase& ph = (it == phases_.begin()) ? phases_.front() : *(it - 1);
  const double tau = std::max(0.0, t - ph.t0_s);

  double cos_yaw = 1.0, sin_yaw = 0.0, yaw_rate = 0.0;
  Eigen::Vector2d xy, v_xy = Eigen::Vector2d::Zero(), a_xy = Eigen::Vector2d::Zero();
  ArcState arc;
  double distance = ph.distance_m;
  if (ph.kind == Phase::Kind::kWalk) {
    const Piece& p = pieces_[ph.piece];
    arc = profile(p, tau);
    auto sit = std::upper_bound(p.spans.begin(), p.spans.end(), arc.s,
                                [](double s, const Span& sp) { return s < sp.s0; });
    const Span& sp = (sit == p.spans.begin()) ? p.spans.front() : *(sit - 1);
    const double u = invert_arc_length(sp, arc.s - sp.s0);
    xy = pos(sp, u);
    const Eigen::Vector2d S1 = d1(sp, u), S2 = d2(sp, u);
    const double n1 = S1.norm();
    const Eigen::Vector2d T = S1 / n1;
    // dT/ds = (S'' |S'|^2 - S' (S'.S'')) / |S'|^4; signed curvature kappa = (S' x S'') / |S'|^3.
    const Eigen::Vector2d K = (S2 * n1 * n1 - S1 * S1.dot(S2)) / (n1 * n1 * n1 * n1);
    const double kappa = (S1.x() * S2.y() - S1.y() * S2.x()) / (n1 * n1 * n1);
    v_xy = T * arc.sd;
    a_xy = K * arc.sd * arc.sd + T * arc.sdd;
    cos_yaw = T.x();
    sin_yaw = T.y();
    yaw_rate = kappa * arc.sd;
    distance = p.distance0_m + arc.s;
  } else {
    xy = ph.xy_m;
    double yaw = ph.yaw0_rad;
    if (ph.kind == Phase::Kind::kTurn) {
      const double dur = ph.t1_s - ph.t0_s;
      const double x = std::clamp(tau / dur, 0.0, 1.0);
      yaw += ph.dyaw_rad * smooth(x);
      yaw_rate = ph.dyaw_rad * smooth_d1(x) / dur;
    }
    cos_yaw = std::cos(yaw);
    sin_yaw = std::sin(yaw);
  }

  // Walking bob: phase advances with distance, one vertical period per step, one roll period per
  // stride (two steps); amplitudes scale with speed so both vanish at stops.
  const double k = 2.0 * M_PI / spec_.step_length_m;
  const double ph_bob = k * distance, ph_d = k * arc.sd, ph_dd = k * arc.sdd;
  const double A = spec_.bob_m_per_mps, B = spec_.roll_rad_per_mps;
  const double sb = std::sin(ph_bob), cb = std::cos(ph_bob);
  const double z = spec_.imu_height_m + A * arc.sd * sb;
  const double zd = A * (arc.sdd * sb + arc.sd * cb * ph_d);
  const double zdd =
      A * (arc.sddd * sb + 2.0 * arc.sdd * cb * ph_d - arc.sd * sb * ph_d * ph_d + arc.sd * cb * ph_dd);
  const double sh = std::sin(0.5 * ph_bob), ch = std::cos(0.5 * ph_bob);
  const double roll = B * arc.sd * sh;
  const double roll_d = B * (arc.sdd * sh + arc.sd * ch * 0.5 * ph_d);

  // R = Rz(yaw) Rx(roll); body rate omega = (roll_d, yaw_d sin(roll), yaw_d cos(roll)).
  Eigen::Matrix3d Rz;
  Rz << cos_yaw, -sin_yaw, 0, sin_yaw, cos_yaw, 0, 0, 0, 1;
  const double cr = std::cos(roll), sr = std::sin(roll);
  Eigen::Matrix3d Rx;
  Rx << 1, 0, 0, 0, cr, -sr, 0, sr, cr;
  st.T_scene_imu.linear() = Rz * Rx;
  st.T_scene_imu.translation() = Eigen::Vector3d(xy.x(), xy.y(), z);
  st.v_scene_mps = Eigen::Vector3d(v_xy.x(), v_xy.y(), zd);
  st.a_scene_mps2 = Eigen::Vector3d(a_xy.x(), a_xy.y(), zdd);
  st.omega_imu_radps = Eigen::Vector3d(roll_d, yaw_rate * sr, yaw_rate * cr);
  st.speed_mps = arc.sd;
  st.distance_m = distance;
  return st;
}

}  // namespace hwr::sim
