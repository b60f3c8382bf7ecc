// `hwr-bench imu`: static initialisation and IMU-only MEKF propagation on real EuRoC data.
//
//  - V1_01_easy (full 145 s IMU, static start): StaticInitializer on the idling-rotor start
//    (thresholds 0.02 rad/s, 0.3 m/s^2: see tests/estimation/test_static_init.cpp), its tilt and
//    gyro-bias errors against the state ground truth, then IMU-only propagation from the init time
//    to the end of the IMU, three ways:
//      (a) the static-init state (gravity-aligned, yaw 0, bg = mean gyro, ba = 0);
//      (b) static init given the GT accel bias as calibration, and the GT gyro bias;
//      (c) the GT state (pose, velocity, both biases) at the init time.
//  - V1_02_medium (40 s IMU, no static start): from the GT state at the first GT sample,
//      (a) = (b) GT pose, velocity and biases; (z) the same with zero biases.
// Alignment: the estimate lives in its own world frame; for (a) and (b) the initial estimated pose
// is aligned to the GT pose at the init time by a yaw rotation about z plus a translation (4 DoF:
// both frames are gravity-aligned, and the yaw of a static init is arbitrary), so tilt errors of the
// initialisation stay visible. (c) and V1_02 start in the GT frame (no alignment). Errors are
// taken at the GT samples nearest to init + 1 s, init + 10 s and the last GT sample within the
// IMU span, with the estimate interpolated there (PoseHistory).
// The per-sample cost is the mean thread CPU time of ImuMekf::propagate (mean + 15x15
// covariance), best of 5 passes over V1_01; the wall time is printed beside it (it includes
// whatever else the machine runs).

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <string>
#include <vector>

#include "bench_command.hpp"
#include "hwr/core/so3.hpp"
#include "hwr/core/time.hpp"
#include "hwr/estimation/imu_mekf.hpp"
#include "hwr/estimation/pose_history.hpp"
#include "hwr/estimation/static_init.hpp"
#include "hwr/hal/sensor_csv.hpp"

namespace hwr::bench {
namespace {

using estimation::ImuMekf;
using estimation::NavState;

constexpr double kRadToDeg = 180.0 / M_PI;

struct Errors {
  double t_s = 0;  // since the init time
  double pos_m = 0, rot_deg = 0, vel_mps = 0;
};

struct RunResult {
  std::vector<Errors> at;  // 1 s, 10 s, end
  size_t samples = 0;
};

// Yaw + translation taking the estimate's world frame to the GT frame, from the initial poses.
struct Align4 {
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  Eigen::Vector3d t = Eigen::Vector3d::Zero();
};

Align4 align_yaw_translation(const NavState& est0, const hal::EurocState& gt0) {
  const Eigen::Vector3d x_gt = gt0.q_world_body.toRotationMatrix().col(0);
  const Eigen::Vector3d x_est = est0.R_world_imu.col(0);
  const double dyaw = std::atan2(x_gt.y(), x_gt.x()) - std::atan2(x_est.y(), x_est.x());
  Align4 a;
  a.R = Eigen::AngleAxisd(dyaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  a.t = gt0.p_world_body - a.R * est0.p_world_imu_m;
  return a;
}

const hal::EurocState& nearest_gt(const std::vector<hal::EurocState>& gt, int64_t t_ns) {
  auto it = std::lower_bound(gt.begin(), gt.end(), t_ns,
                             [](const hal::EurocState& s, int64_t t) { return s.t_ns < t; });
  if (it == gt.end()) return gt.back();
  if (it != gt.begin() && t_ns - std::prev(it)->t_ns < it->t_ns - t_ns) return *std::prev(it);
  return *it;
}

// Propagates from x0 over imu[first..] and evaluates against the GT at init + 1 s, + 10 s, end.
RunResult propagate_and_score(const NavState& x0, const Align4& align, const std::vector<hal::ImuSample>& imu,
                              size_t first, const std::vector<hal::EurocState>& gt) {
  ImuMekf mekf;
  mekf.initialize(x0, ImuMekf::Cov15::Identity() * 1e-6);
  estimation::PoseHistory history(imu.size() - first + 1);
  for (size_t k = first; k < imu.size(); ++k) {
    if (!mekf.propagate(imu[k])) continue;
    history.push(mekf.state());
  }
  RunResult r;
  r.samples = history.size();
  // The last GT sample inside the propagated span.
  int64_t t_end = gt.front().t_ns;
  for (const hal::EurocState& g : gt) {
    if (g.t_ns <= history.newest_t_ns()) t_end = std::max(t_end, g.t_ns);
  }
  for (const int64_t target : {x0.t_ns + core::kNsPerS, x0.t_ns + 10 * core::kNsPerS, t_end}) {
    const hal::EurocState& g = nearest_gt(gt, std::min(target, t_end));
    NavState s;
    if (!history.interpolate_state(g.t_ns, &s).ok()) continue;
    Errors e;
    e.t_s = core::ns_to_s(g.t_ns - x0.t_ns);
    e.pos_m = (align.R * s.p_world_imu_m + align.t - g.p_world_body).norm();
    e.vel_mps = (align.R * s.v_world_mps - g.v_world_body_mps).norm();
    e.rot_deg =
        core::so3_log(g.q_world_body.toRotationMatrix().transpose() * align.R * s.R_world_imu).norm() *
        kRadToDeg;
    r.at.push_back(e);
  }
  return r;
}

NavState gt_state(const hal::EurocState& g, int64_t t_ns, bool with_biases) {
  NavState x;
  x.t_ns = t_ns;
  x.R_world_imu = g.q_world_body.toRotationMatrix();
  x.p_world_imu_m = g.p_world_body;
  x.v_world_mps = g.v_world_body_mps;
  if (with_biases) {
    x.gyro_bias_radps = g.gyro_bias_radps;
    x.accel_bias_mps2 = g.accel_bias_mps2;
  }
  return x;
}

void print_row(const char* name, const RunResult& r) {
  std::printf("  %-34s", name);
  for (const Errors& e : r.at)
    std::printf(" | %6.1fs %9.3f m %7.2f deg %7.3f m/s", e.t_s, e.pos_m, e.rot_deg, e.vel_mps);
  std::printf("\n");
}

void print_keys(const char* prefix, const char* suffix, const RunResult& r) {
  static const char* kAt[] = {"1s", "10s", "end"};
  for (size_t i = 0; i < r.at.size() && i < 3; ++i) {
    std::printf("imu_only_pos_err_m_%s_%s%s=%.4f\n", prefix, kAt[i], suffix, r.at[i].pos_m);
    std::printf("imu_only_rot_err_deg_%s_%s%s=%.4f\n", prefix, kAt[i], suffix, r.at[i].rot_deg);
    std::printf("imu_only_vel_err_mps_%s_%s%s=%.4f\n", prefix, kAt[i], suffix, r.at[i].vel_mps);
  }
}

double thread_cpu_ns() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) * 1e9 + static_cast<double>(ts.tv_nsec);
}

struct Cost {
  double cpu_ns = 0;   // thread CPU time per call (insensitive to other processes on the machine)
  double wall_ns = 0;  // wall time per call
};

// Mean cost per propagate() over all samples, best of `reps` passes.
Cost time_propagate(const NavState& x0, const std::vector<hal::ImuSample>& imu, size_t first, int reps) {
  Cost best{1e300, 1e300};
  for (int rep = 0; rep < reps; ++rep) {
    ImuMekf mekf;
    mekf.initialize(x0, ImuMekf::Cov15::Identity() * 1e-6);
    const double c0 = thread_cpu_ns();
    const auto t0 = std::chrono::steady_clock::now();
    for (size_t k = first; k < imu.size(); ++k) mekf.propagate(imu[k]);
    const auto t1 = std::chrono::steady_clock::now();
    const double c1 = thread_cpu_ns();
    const double n = static_cast<double>(mekf.counters().propagated);
    best.cpu_ns = std::min(best.cpu_ns, (c1 - c0) / n);
    best.wall_ns = std::min(best.wall_ns, std::chrono::duration<double, std::nano>(t1 - t0).count() / n);
  }
  return best;
}

// Mean cost per update_pose() (6-dof, Joseph form, reset): batches of 64 updates between
// propagations, so the clock reads do not dominate.
Cost time_update(const NavState& x0, const std::vector<hal::ImuSample>& imu, size_t first) {
  ImuMekf mekf;
  mekf.initialize(x0, ImuMekf::Cov15::Identity() * 1e-4);
  const Eigen::Matrix<double, 6, 6> cov = Eigen::Matrix<double, 6, 6>::Identity() * 1e-4;
  Cost total;
  size_t n = 0;
  for (size_t k = first; k < imu.size() && n < 64 * 500; ++k) {
    mekf.propagate(imu[k]);
    const Eigen::Isometry3d T = mekf.state().T_world_imu();
    const double c0 = thread_cpu_ns();
    const auto t0 = std::chrono::steady_clock::now();
    for (int i = 0; i < 64; ++i) mekf.update_pose(T, cov, 1e9);
    const auto t1 = std::chrono::steady_clock::now();
    total.cpu_ns += thread_cpu_ns() - c0;
    total.wall_ns += std::chrono::duration<double, std::nano>(t1 - t0).count();
    n += 64;
  }
  total.cpu_ns /= static_cast<double>(std::max<size_t>(n, 1));
  total.wall_ns /= static_cast<double>(std::max<size_t>(n, 1));
  return total;
}

int run_imu(int argc, char** argv) {
  std::string data_dir = HWR_DATA_DIR;
  for (int a = 1; a < argc; ++a) {
    if (std::strncmp(argv[a], "--data=", 7) == 0) {
      data_dir = argv[a] + 7;
    } else {
      std::fprintf(stderr, "imu: unknown argument '%s' (use --data=DIR)\n", argv[a]);
      return 2;
    }
  }
  const std::string v101 = data_dir + "/euroc-v1-01-static-start/mav0";
  const std::string v102 = data_dir + "/euroc-v1-02-imu-40s/mav0";
  auto imu1 = hal::read_imu_csv(v101 + "/imu0/data.csv");
  auto gt1 = hal::read_euroc_state_csv(v101 + "/state_groundtruth_estimate0/data.csv");
  auto imu2 = hal::read_imu_csv(v102 + "/imu0/data.csv");
  auto gt2 = hal::read_euroc_state_csv(v102 + "/gt0/data.csv");
  for (const core::Status& st : {imu1.status(), gt1.status(), imu2.status(), gt2.status()}) {
    if (!st.ok()) {
      std::fprintf(stderr, "imu: %s\n", st.to_string().c_str());
      return 1;
    }
  }

  // --- V1_01: static initialisation ----------------------------------------------------------
  estimation::StaticInitConfig cfg;
  cfg.max_gyro_std_radps = 0.02;
  cfg.max_accel_std_mps2 = 0.3;
  estimation::StaticInitializer init(cfg);
  size_t k_init = 0;
  for (; k_init < imu1->size(); ++k_init) {
    init.add_imu((*imu1)[k_init]);
    if (init.ready()) break;
  }
  auto x_init = init.result();
  if (!x_init.ok()) {
    std::fprintf(stderr, "imu: V1_01 static init failed: %s\n", x_init.status().to_string().c_str());
    return 1;
  }
  const hal::EurocState& g_init = nearest_gt(*gt1, x_init->t_ns);
  const Eigen::Matrix3d R_gt_init = g_init.q_world_body.toRotationMatrix();
  const Eigen::Vector3d up_gt = R_gt_init.transpose() * Eigen::Vector3d::UnitZ();
  const Eigen::Vector3d up_est = x_init->R_world_imu.transpose() * Eigen::Vector3d::UnitZ();
  const double tilt_err_deg = std::atan2(up_gt.cross(up_est).norm(), up_gt.dot(up_est)) * kRadToDeg;
  const Eigen::Vector3d bg_err = x_init->gyro_bias_radps - g_init.gyro_bias_radps;
  const double init_after_s = core::ns_to_s(x_init->t_ns - imu1->front().t_ns);

  // (b): calibrated with the GT accel bias, GT gyro bias.
  estimation::StaticInitConfig cfg_b = cfg;
  cfg_b.accel_bias_mps2 = g_init.accel_bias_mps2;
  estimation::StaticInitializer init_b(cfg_b);
  for (size_t k = 0; k <= k_init; ++k) init_b.add_imu((*imu1)[k]);
  auto x_b = init_b.result();
  if (!x_b.ok()) {
    std::fprintf(stderr, "imu: V1_01 calibrated static init failed: %s\n", x_b.status().to_string().c_str());
    return 1;
  }
  x_b->gyro_bias_radps = g_init.gyro_bias_radps;

  const RunResult r1a =
      propagate_and_score(*x_init, align_yaw_translation(*x_init, g_init), *imu1, k_init, *gt1);
  const RunResult r1b = propagate_and_score(*x_b, align_yaw_translation(*x_b, g_init), *imu1, k_init, *gt1);
  const RunResult r1c =
      propagate_and_score(gt_state(g_init, x_init->t_ns, true), Align4{}, *imu1, k_init, *gt1);

  // --- V1_02: from the GT state at the first GT sample ----------------------------------------
  const hal::EurocState& g2 = gt2->front();
  size_t k2 = 0;
  while (k2 + 1 < imu2->size() && (*imu2)[k2].t_ns < g2.t_ns) ++k2;
  const int64_t t2 = (*imu2)[k2].t_ns;
  const RunResult r2a = propagate_and_score(gt_state(g2, t2, true), Align4{}, *imu2, k2, *gt2);
  const RunResult r2z = propagate_and_score(gt_state(g2, t2, false), Align4{}, *imu2, k2, *gt2);

  const Cost prop = time_propagate(*x_init, *imu1, k_init, 5);
  const Cost upd = time_update(*x_init, *imu1, k_init);

  std::printf("imu: EuRoC static initialisation and IMU-only MEKF propagation (gravity 9.81)\n");
  std::printf(
      "  V1_01 static init after %.2f s (1-s window, gyro std %.4f rad/s, accel std %.3f m/s^2 max)\n",
      init_after_s, init.diagnostics().gyro_std_radps.maxCoeff(),
      init.diagnostics().accel_std_mps2.maxCoeff());
  std::printf("    gravity tilt error vs GT     %.3f deg (accel-bias floor |b_a|/g = %.3f deg)\n",
              tilt_err_deg, g_init.accel_bias_mps2.norm() / cfg.gravity_mps2 * kRadToDeg);
  std::printf("    gyro bias error vs GT        (%.2e, %.2e, %.2e) rad/s\n", bg_err.x(), bg_err.y(),
              bg_err.z());
  std::printf(
      "  IMU-only propagation: error vs GT at init + 1 s, + 10 s, end (4-DoF aligned at init for a, b)\n");
  print_row("V1_01 (a) static init", r1a);
  print_row("V1_01 (b) static init + GT biases", r1b);
  print_row("V1_01 (c) GT state", r1c);
  print_row("V1_02 (a=b) GT state incl. biases", r2a);
  print_row("V1_02 (z) GT pose, zero biases", r2z);
  std::printf("  propagate   %8.1f ns/sample CPU (%.1f wall; mean + 15x15 covariance, one thread)\n",
              prop.cpu_ns, prop.wall_ns);
  std::printf("  update_pose %8.1f ns/update CPU (%.1f wall; 6-dof, Joseph form, reset)\n", upd.cpu_ns,
              upd.wall_ns);

  std::printf("imu_static_init_after_s=%.3f\n", init_after_s);
  std::printf("imu_static_tilt_err_deg=%.4f\n", tilt_err_deg);
  std::printf("imu_static_gyro_bias_err_radps=%.6f\n", bg_err.cwiseAbs().maxCoeff());
  print_keys("v1_01", "", r1a);
  print_keys("v1_01", "_gtbias", r1b);
  print_keys("v1_01", "_gtinit", r1c);
  print_keys("v1_02", "", r2a);
  print_keys("v1_02", "_zerobias", r2z);
  std::printf("mekf_propagate_ns=%.1f\n", prop.cpu_ns);
  std::printf("mekf_propagate_wall_ns=%.1f\n", prop.wall_ns);
  std::printf("mekf_update_pose_ns=%.1f\n", upd.cpu_ns);
  return 0;
}

}  // namespace

HWR_BENCH_COMMAND(imu, "imu",
                  "EuRoC V1_01/V1_02: static init errors, IMU-only MEKF propagation error, ns/sample "
                  "(--data=DIR)",
                  run_imu);

}  // namespace hwr::bench
