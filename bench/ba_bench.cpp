// `hwr-bench ba`: the hand-written sparse bundle adjuster (estimation/ba_solver.hpp) against Ceres
// (SPARSE_SCHUR, one thread) on the same problems, from the same start, with the same loss and
// iteration limit (acceptance of issue #3 item 6: >= 2x faster than Ceres to the same final cost).
//
// Problems: Ladybug 49-7776 (BAL, full), its 1800-point reduction, a synthetic pinhole RGB-D
// keyframe window (30 keyframes, 6000 points, 2 % outliers, depth on 60 % of the observations,
// the first keyframe fixed), and problems exported from our own runs: the end-of-run full bundle
// adjustment of the pipeline on TUM teddy (real RGB-D) and on the first 30 s of sim lab, built
// from the run's keyframes and points exactly as the estimator would solve them (depth residuals,
// oldest keyframe fixed). --problem-file=FILE adds any BAL file (hwr-robot --ba-export writes one). BAL
// intrinsics (f, k1, k2) are held fixed by both solvers: Ceres gets them as constants of its autodiff functor
// and the pose as 6 parameters (angle-axis, t), the canonical BAL example without the intrinsics block.
//
// Figures: initial cost, final cost of each, total solve time of each, and the time each needs to
// reach the common target = (worse of the two final costs) * 1.001: the cost is recorded after
// every iteration with its elapsed time (ours: BaOptions::iteration_callback; Ceres:
// IterationCallback with cumulative_time_in_seconds, i.e. including its preprocessing), and the
// first iteration at or under the target counts (no interpolation). Both run to convergence (at
// most --iterations, default 200: the gauge-free Ladybug problem needs ~100 with either solver).
// Problem construction (ours:
// the solver's workspace; Ceres: ceres::Problem) is not timed. Each solve runs --reps times
// (default 3); times are medians.

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <random>
#include <string>
#include <utility>
#include <vector>

#if HWR_HAVE_CERES
#include <ceres/ceres.h>
#include <ceres/rotation.h>
#endif

#include "bench_command.hpp"
#include "hwr/core/se3.hpp"
#include "hwr/core/so3.hpp"
#include "hwr/estimation/ba_problem.hpp"
#include "hwr/estimation/ba_solver.hpp"
#include "hwr/estimation/bal_format.hpp"
#include "hwr/estimation/local_bundle_adjustment.hpp"
#include "hwr/estimation/offline_run.hpp"
#include "hwr/hal/replay_source.hpp"
#if HWR_WITH_SIM
#include "hwr/sim/scenario.hpp"
#include "hwr/sim/sim_live_log.hpp"
#endif

namespace hwr::bench {
namespace {

using estimation::BaCameraModel;
using estimation::BaObservation;
using estimation::BaOptions;
using estimation::BaProblem;

struct Trace {
  std::vector<std::pair<double, double>> elapsed_cost;  // (s, cost of the current estimate)
};

struct RunResult {
  double initial_cost = 0;
  double final_cost = 0;
  double total_s = 0;
  int iterations = 0;
  bool converged = false;
  Trace trace;
};

// Time of the first recorded iteration at or under target; NaN if none.
double time_to(const Trace& t, double target) {
  for (const auto& [s, c] : t.elapsed_cost) {
    if (c <= target) return s;
  }
  return std::nan("");
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? std::nan("") : v[v.size() / 2];
}

// --- ours -----------------------------------------------------------------------------------------

void record_ours(const estimation::BaIterationInfo& info, void* user) {
  static_cast<Trace*>(user)->elapsed_cost.emplace_back(info.elapsed_s, info.cost);
}

RunResult run_ours(const BaProblem& start, const BaOptions& base, BaProblem* out) {
  BaProblem pb = start;
  estimation::BaCapacity cap{static_cast<int>(pb.cameras.size()), static_cast<int>(pb.points.size()),
                             static_cast<int>(pb.observations.size())};
  estimation::SparseBundleAdjuster solver(cap);
  RunResult r;
  r.trace.elapsed_cost.reserve(static_cast<size_t>(base.max_iterations) + 2);
  BaOptions opt = base;
  opt.iteration_callback = &record_ours;
  opt.callback_user = &r.trace;
  const auto t0 = std::chrono::steady_clock::now();
  const auto s = solver.solve(&pb, opt);
  r.total_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (!s.ok()) {
    std::fprintf(stderr, "ba: our solver failed: %s\n", s.status().to_string().c_str());
    std::exit(1);
  }
  r.initial_cost = s->initial_cost;
  r.final_cost = s->final_cost;
  r.iterations = s->iterations;
  r.converged = s->converged;
  if (out != nullptr) *out = std::move(pb);
  return r;
}

// --- Ceres ----------------------------------------------------------------------------------------
#if HWR_HAVE_CERES

template <class T>
void transform_point(const T* pose, const T* X, T* P) {
  ceres::AngleAxisRotatePoint(pose, X, P);
  P[0] += pose[3];
  P[1] += pose[4];
  P[2] += pose[5];
}

// Snavely's model with f, k1, k2 as constants.
struct BalReprojection {
  double u, v, inv_sigma, f, k1, k2;
  template <class T>
  bool operator()(const T* pose, const T* X, T* r) const {
    T P[3];
    transform_point(pose, X, P);
    const T xp = -P[0] / P[2], yp = -P[1] / P[2];
    const T n2 = xp * xp + yp * yp;
    const T d = 1.0 + n2 * (k1 + k2 * n2);
    r[0] = (f * d * xp - u) * inv_sigma;
    r[1] = (f * d * yp - v) * inv_sigma;
    return true;
  }
};

struct PinholeReprojection {
  double u, v, inv_sigma, fx, fy, cx, cy;
  template <class T>
  bool operator()(const T* pose, const T* X, T* r) const {
    T P[3];
    transform_point(pose, X, P);
    r[0] = (fx * P[0] / P[2] + cx - u) * inv_sigma;
    r[1] = (fy * P[1] / P[2] + cy - v) * inv_sigma;
    return true;
  }
};

struct DepthResidual {
  double depth, inv_sigma, sign;
  template <class T>
  bool operator()(const T* pose, const T* X, T* r) const {
    T P[3];
    transform_point(pose, X, P);
    r[0] = (sign * P[2] - depth) * inv_sigma;
    return true;
  }
};

class CeresRecorder : public ceres::IterationCallback {
 public:
  explicit CeresRecorder(Trace* t) : trace_(t) {}
  ceres::CallbackReturnType operator()(const ceres::IterationSummary& s) override {
    if (s.step_is_successful) trace_->elapsed_cost.emplace_back(s.cumulative_time_in_seconds, s.cost);
    return ceres::SOLVER_CONTINUE;
  }

 private:
  Trace* trace_;
};

RunResult run_ceres(const BaProblem& start, const BaOptions& opt, BaProblem* out) {
  FLAGS_minloglevel =
      2;  // glog: keep Ceres' per-iteration warnings (e.g. CHOLMOD "not positive definite") quiet
  const size_t nc = start.cameras.size(), np = start.points.size();
  std::vector<double> poses(6 * nc), points(3 * np);
  for (size_t c = 0; c < nc; ++c) {
    const Eigen::Isometry3d& T = start.cameras[c].T_cam_world;
    const Eigen::Vector3d w = core::so3_log(T.linear());
    for (int i = 0; i < 3; ++i) {
      poses[6 * c + static_cast<size_t>(i)] = w[i];
      poses[6 * c + 3 + static_cast<size_t>(i)] = T.translation()[i];
    }
  }
  for (size_t p = 0; p < np; ++p) {
    for (int i = 0; i < 3; ++i) points[3 * p + static_cast<size_t>(i)] = start.points[p].p_world[i];
  }
  ceres::Problem::Options popt;
  popt.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  ceres::Problem problem(popt);
  std::unique_ptr<ceres::LossFunction> loss;
  if (opt.huber_px > 0) loss = std::make_unique<ceres::HuberLoss>(opt.huber_px);
  const bool pinhole = start.model == BaCameraModel::kPinhole;
  for (const BaObservation& o : start.observations) {
    const estimation::BaIntrinsics& K = start.cameras[static_cast<size_t>(o.camera)].K;
    double* pose = &poses[6 * static_cast<size_t>(o.camera)];
    double* X = &points[3 * static_cast<size_t>(o.point)];
    ceres::CostFunction* cf = nullptr;
    if (pinhole) {
      cf = new ceres::AutoDiffCostFunction<PinholeReprojection, 2, 6, 3>(
          new PinholeReprojection{o.uv_px.x(), o.uv_px.y(), 1.0 / o.sigma_px, K.fx, K.fy, K.cx, K.cy});
    } else {
      cf = new ceres::AutoDiffCostFunction<BalReprojection, 2, 6, 3>(
          new BalReprojection{o.uv_px.x(), o.uv_px.y(), 1.0 / o.sigma_px, K.f, K.k1, K.k2});
    }
    problem.AddResidualBlock(cf, loss.get(), pose, X);
    if (opt.use_depth && o.depth_m > 0) {
      const double sigma = estimation::ba_depth_sigma_m(o.depth_m, opt.depth_sigma_per_m2);
      problem.AddResidualBlock(new ceres::AutoDiffCostFunction<DepthResidual, 1, 6, 3>(
                                   new DepthResidual{o.depth_m, 1.0 / sigma, pinhole ? 1.0 : -1.0}),
                               loss.get(), pose, X);
    }
  }
  auto ordering = std::make_shared<ceres::ParameterBlockOrdering>();
  for (size_t p = 0; p < np; ++p) {
    if (problem.HasParameterBlock(&points[3 * p])) {
      ordering->AddElementToGroup(&points[3 * p], 0);
      if (start.points[p].fixed) problem.SetParameterBlockConstant(&points[3 * p]);
    }
  }
  for (size_t c = 0; c < nc; ++c) {
    if (problem.HasParameterBlock(&poses[6 * c])) {
      ordering->AddElementToGroup(&poses[6 * c], 1);
      if (start.cameras[c].fixed) problem.SetParameterBlockConstant(&poses[6 * c]);
    }
  }
  RunResult r;
  CeresRecorder recorder(&r.trace);
  ceres::Solver::Options so;
  so.linear_solver_type = ceres::SPARSE_SCHUR;
  so.linear_solver_ordering = ordering;
  so.num_threads = 1;
  so.max_num_iterations = opt.max_iterations;
  so.function_tolerance = opt.function_tolerance;
  so.gradient_tolerance = opt.gradient_tolerance;
  so.parameter_tolerance = opt.parameter_tolerance;
  so.initial_trust_region_radius = 1.0 / opt.initial_lambda;
  so.logging_type = ceres::SILENT;
  so.minimizer_progress_to_stdout = false;
  so.callbacks.push_back(&recorder);
  ceres::Solver::Summary summary;
  const auto t0 = std::chrono::steady_clock::now();
  ceres::Solve(so, &problem, &summary);
  r.total_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  r.initial_cost = summary.initial_cost;
  r.final_cost = summary.final_cost;
  r.iterations = static_cast<int>(summary.iterations.size()) - 1;
  r.converged = summary.termination_type == ceres::CONVERGENCE;
  if (out != nullptr) {
    *out = start;
    for (size_t c = 0; c < nc; ++c) {
      Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
      T.linear() = core::so3_exp(Eigen::Vector3d(poses[6 * c], poses[6 * c + 1], poses[6 * c + 2]));
      T.translation() = Eigen::Vector3d(poses[6 * c + 3], poses[6 * c + 4], poses[6 * c + 5]);
      out->cameras[c].T_cam_world = T;
    }
    for (size_t p = 0; p < np; ++p) {
      out->points[p].p_world = Eigen::Vector3d(points[3 * p], points[3 * p + 1], points[3 * p + 2]);
    }
  }
  return r;
}
#endif  // HWR_HAVE_CERES

// --- problems -------------------------------------------------------------------------------------

// A keyframe window as the tracker builds it: 30 pinhole RGB-D keyframes 0.5 m apart along a
// 15 m corridor wall, 6000 points, ~0.7 px noise, depth with sigma = c z^2 on 60 % of the
// observations, 2 % gross outliers; start perturbed by 2 cm / 1 degree (poses) and 3 cm (points).
BaProblem synthetic_rgbd_window(const BaOptions& opt) {
  std::mt19937 rng(42);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  std::normal_distribution<double> n01(0.0, 1.0);
  BaProblem pb;
  pb.model = BaCameraModel::kPinhole;
  estimation::BaIntrinsics K;
  K.fx = 525.0;
  K.fy = 525.0;
  K.cx = 319.5;
  K.cy = 239.5;
  const int n_kf = 30, n_points = 6000;
  for (int k = 0; k < n_kf; ++k) {
    // World z up; camera looks along +y (OpenCV axes: x right, y down, z forward), small yaw.
    const double yaw = 0.15 * std::sin(0.4 * k);
    Eigen::Matrix3d R_world_cam;
    R_world_cam << 1, 0, 0, 0, 0, 1, 0, -1, 0;
    R_world_cam = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix() * R_world_cam;
    Eigen::Isometry3d T_world_cam = Eigen::Isometry3d::Identity();
    T_world_cam.linear() = R_world_cam;
    T_world_cam.translation() = Eigen::Vector3d(0.5 * k, 0.05 * std::sin(0.7 * k), 1.5);
    estimation::BaCamera cam;
    cam.T_cam_world = T_world_cam.inverse();
    cam.K = K;
    cam.fixed = k == 0;
    pb.cameras.push_back(cam);
  }
  for (int p = 0; p < n_points; ++p) {
    estimation::BaPoint pt;
    pt.p_world = Eigen::Vector3d(-2.0 + 18.5 * u01(rng), 2.0 + 4.0 * u01(rng), 3.0 * u01(rng));
    pb.points.push_back(pt);
  }
  std::vector<int> seen(static_cast<size_t>(n_points), 0);
  for (int p = 0; p < n_points; ++p) {
    for (int k = 0; k < n_kf; ++k) {
      const estimation::BaCamera& cam = pb.cameras[static_cast<size_t>(k)];
      const Eigen::Vector3d p_cam = cam.T_cam_world * pb.points[static_cast<size_t>(p)].p_world;
      if (p_cam.z() < 0.3 || p_cam.z() > 8.0) continue;
      const Eigen::Vector2d uv = estimation::ba_project<BaCameraModel::kPinhole>(K, p_cam);
      if (uv.x() < 0 || uv.x() > 639 || uv.y() < 0 || uv.y() > 479) continue;
      BaObservation o;
      o.camera = k;
      o.point = p;
      o.uv_px = uv + 0.7 * Eigen::Vector2d(n01(rng), n01(rng));
      if (u01(rng) < 0.02) {
        const double a = 2 * M_PI * u01(rng);
        o.uv_px += (10.0 + 40.0 * u01(rng)) * Eigen::Vector2d(std::cos(a), std::sin(a));
      }
      if (u01(rng) < 0.6) {
        o.depth_m = p_cam.z() + estimation::ba_depth_sigma_m(p_cam.z(), opt.depth_sigma_per_m2) * n01(rng);
      }
      pb.observations.push_back(o);
      ++seen[static_cast<size_t>(p)];
    }
  }
  // Perturb the start.
  for (estimation::BaCamera& cam : pb.cameras) {
    if (cam.fixed) continue;
    core::Vector6d d;
    for (int i = 0; i < 3; ++i) d[i] = 0.02 / std::sqrt(3.0) * n01(rng);
    for (int i = 3; i < 6; ++i) d[i] = (M_PI / 180.0) / std::sqrt(3.0) * n01(rng);
    cam.T_cam_world = core::se3_exp(d) * cam.T_cam_world;
  }
  for (estimation::BaPoint& pt : pb.points) {
    pt.p_world += 0.03 / std::sqrt(3.0) * Eigen::Vector3d(n01(rng), n01(rng), n01(rng));
  }
  return pb;
}

// The full bundle adjustment a pipeline run would end with, taken just before it runs (the run
// itself skips it): every keyframe in the ring that observes points, the oldest fixed.
core::Expected<BaProblem> problem_from_run(const hal::ReplayLog& log) {
  estimation::OfflineRunOptions run_opt;
  run_opt.estimator.full_ba_at_end = false;
  BaProblem out;
  const size_t last = log.frame_t_ns.empty() ? 0 : log.frame_t_ns.size() - 1;
  run_opt.after_frame = [&](size_t i, const estimation::PoseEstimator& e) {
    if (i != last) return;
    estimation::LocalBundleAdjustment lba(run_opt.estimator.local_ba,
                                          run_opt.estimator.tracker.map_point_capacity);
    estimation::LocalBaReport report;
    out = lba.build_problem(e.tracker().keyframes(), e.tracker().points(), e.tracker().intrinsics(), true,
                            &report);
  };
  auto run = estimation::run_offline(log, run_opt);
  if (!run.ok()) return run.status();
  if (out.cameras.size() < 2) return core::Internal("the run produced fewer than 2 keyframes");
  return out;
}

core::Expected<BaProblem> problem_from_named_run(const std::string& name) {
  if (name == "teddy_full") {
    auto log = hal::open_dataset_log("tum:" HWR_DATA_DIR "/tum-fr3-teddy-200/rgbd_dataset_freiburg3_teddy");
    if (!log.ok()) return log.status();
    return problem_from_run(log.value());
  }
#if HWR_WITH_SIM
  auto spec = sim::load_scenario("lab");
  if (!spec.ok()) return spec.status();
  auto live = sim::open_sim_live_log(spec.value(), 30.0);
  if (!live.ok()) return live.status();
  return problem_from_run(live->log);
#else
  return core::Unavailable(name + ": this build has no simulator");
#endif
}

struct BenchProblem {
  std::string name;
  BaProblem problem;
};

int run_ba(int argc, char** argv) {
  int reps = 3;
  bool with_peer = true;
  std::string only;
  std::vector<std::string> files;
  BaOptions opt;
  // Enough for both solvers to converge on the gauge-free Ladybug problem (both need ~100).
  opt.max_iterations = 200;
  for (int a = 1; a < argc; ++a) {
    if (std::strncmp(argv[a], "--reps=", 7) == 0) {
      reps = std::max(1, std::atoi(argv[a] + 7));
    } else if (std::strncmp(argv[a], "--iterations=", 13) == 0) {
      opt.max_iterations = std::max(1, std::atoi(argv[a] + 13));
    } else if (std::strncmp(argv[a], "--huber=", 8) == 0) {
      opt.huber_px = std::atof(argv[a] + 8);
    } else if (std::strcmp(argv[a], "--no-ceres") == 0) {
      with_peer = false;
    } else if (std::strncmp(argv[a], "--problem=", 10) == 0) {
      only = argv[a] + 10;
    } else if (std::strncmp(argv[a], "--problem-file=", 15) == 0) {
      files.push_back(argv[a] + 15);
    } else {
      std::fprintf(stderr,
                   "ba: unknown argument '%s' (use --reps=N, --iterations=N, --huber=PX (<= 0: squared), "
                   "--problem=ladybug49|ladybug49_1800|rgbd_window|teddy_full|lab_full_30s, "
                   "--problem-file=FILE.bal, --no-ceres)\n",
                   argv[a]);
      return 2;
    }
  }
  // --problem-file alone benches just the files; with --problem=NAME, that built-in as well.
  if (!files.empty() && only.empty()) only = "-";
  std::vector<BenchProblem> problems;
  const std::pair<const char*, const char*> bal_files[] = {
      {"ladybug49", HWR_DATA_DIR "/bal-ladybug/bal/ladybug/problem-49-7776-pre.txt"},
      {"ladybug49_1800", HWR_DATA_DIR "/bal-ladybug/test/bal-ladybug-problem-49-7776-pre-shrink-1800.txt"},
  };
  for (const auto& [name, path] : bal_files) {
    if (!only.empty() && only != name) continue;
    auto pb = estimation::read_bal(path);
    if (!pb.ok()) {
      std::fprintf(stderr, "ba: %s\n", pb.status().to_string().c_str());
      return 1;
    }
    problems.push_back({name, std::move(pb).value()});
  }
  if (only.empty() || only == "rgbd_window") problems.push_back({"rgbd_window", synthetic_rgbd_window(opt)});
  for (const char* name : {"teddy_full", "lab_full_30s"}) {
    if (!only.empty() && only != name) continue;
    auto pb = problem_from_named_run(name);
    if (!pb.ok()) {
      std::fprintf(stderr, "ba: %s: %s\n", name, pb.status().to_string().c_str());
      return 1;
    }
    problems.push_back({name, std::move(pb).value()});
  }
  for (const std::string& path : files) {
    auto pb = estimation::read_bal(path);
    if (!pb.ok()) {
      std::fprintf(stderr, "ba: %s\n", pb.status().to_string().c_str());
      return 1;
    }
    // The gauge: BAL has no fixed flags, so the first camera is held (as the exporter's oldest was).
    if (!pb->cameras.empty()) pb->cameras.front().fixed = true;
    const size_t slash = path.find_last_of('/');
    problems.push_back(
        {"file:" + path.substr(slash == std::string::npos ? 0 : slash + 1), std::move(pb).value()});
  }
  if (problems.empty() || (only != "-" && only != "" && problems.size() == files.size())) {
    std::fprintf(stderr, "ba: unknown --problem=%s\n", only.c_str());
    return 2;
  }

#if HWR_HAVE_CERES
  const bool have_ceres = with_peer;
  if (have_ceres) {
    std::printf("ba: hand-written LM + Schur vs Ceres %s (SPARSE_SCHUR, 1 thread); ", CERES_VERSION_STRING);
  } else {
    std::printf("ba: hand-written LM + Schur (--no-ceres); ");
  }
#else
  const bool have_ceres = false;
  (void)with_peer;
  std::printf("ba: hand-written LM + Schur (Ceres not built in: no peer); ");
#endif
  std::printf("Huber %.2f, max %d iterations, median of %d; BAL intrinsics fixed for both\n", opt.huber_px,
              opt.max_iterations, reps);
  std::printf("  %-15s %5s %6s %6s %13s %13s %13s %7s %7s %9s %9s %9s %9s %8s\n", "problem", "cams", "points",
              "obs", "initial cost", "ours final", "ceres final", "it", "it(c)", "ours ms", "ceres ms",
              "ours->t", "ceres->t", "speedup");
  struct Keys {
    std::string name;
    double ours_ms, ceres_ms, speedup, ours_total_ms, ceres_total_ms, ours_final, ceres_final;
  };
  std::vector<Keys> keys;
  for (const BenchProblem& bp : problems) {
    // Interleaved, so that a change in machine load hits both solvers alike.
    std::vector<RunResult> ours, ceres;
    for (int r = 0; r < reps; ++r) {
      ours.push_back(run_ours(bp.problem, opt, nullptr));
#if HWR_HAVE_CERES
      if (have_ceres) ceres.push_back(run_ceres(bp.problem, opt, nullptr));
#endif
    }
    const RunResult& o0 = ours.front();
    const double ceres_final = have_ceres ? ceres.front().final_cost : o0.final_cost;
    const double target = std::max(o0.final_cost, ceres_final) * 1.001;
    std::vector<double> o_total, o_to, c_total, c_to;
    for (const RunResult& r : ours) {
      o_total.push_back(1e3 * r.total_s);
      o_to.push_back(1e3 * time_to(r.trace, target));
    }
    for (const RunResult& r : ceres) {
      c_total.push_back(1e3 * r.total_s);
      c_to.push_back(1e3 * time_to(r.trace, target));
    }
    Keys k{bp.name,         median(o_to),    median(c_to),  0,
           median(o_total), median(c_total), o0.final_cost, ceres_final};
    k.speedup = have_ceres ? k.ceres_ms / k.ours_ms : std::nan("");
    const bool ceres_converged = have_ceres && ceres.front().converged;
    std::printf("  %-15s %5zu %6zu %6zu %13.6g %13.6g %13.6g %6d%s %6d%s %9.2f %9.2f %9.2f %9.2f %7.2fx\n",
                bp.name.c_str(), bp.problem.cameras.size(), bp.problem.points.size(),
                bp.problem.observations.size(), o0.initial_cost, o0.final_cost, ceres_final, o0.iterations,
                o0.converged ? "c" : " ", have_ceres ? ceres.front().iterations : 0,
                ceres_converged ? "c" : " ", k.ours_total_ms, have_ceres ? k.ceres_total_ms : std::nan(""),
                k.ours_ms, k.ceres_ms, k.speedup);
    if (have_ceres && std::abs(ceres.front().initial_cost - o0.initial_cost) > 1e-6 * o0.initial_cost) {
      std::printf("  WARNING %s: initial costs differ (ours %.9g, Ceres %.9g): not the same problem\n",
                  bp.name.c_str(), o0.initial_cost, ceres.front().initial_cost);
    }
    keys.push_back(k);
  }
  std::printf(
      "  (it: iterations, c = converged; ms: total solve; ->t: time to reach max(final costs) * 1.001;\n"
      "   speedup = ceres->t / ours->t)\n");
  for (const Keys& k : keys) {
    std::printf("ba_ms_%s=%.3f\n", k.name.c_str(), k.ours_ms);
    if (have_ceres) std::printf("ceres_ms_%s=%.3f\n", k.name.c_str(), k.ceres_ms);
    if (have_ceres) std::printf("ba_speedup_vs_ceres_%s=%.2f\n", k.name.c_str(), k.speedup);
    std::printf("ba_total_ms_%s=%.3f\n", k.name.c_str(), k.ours_total_ms);
    if (have_ceres) std::printf("ceres_total_ms_%s=%.3f\n", k.name.c_str(), k.ceres_total_ms);
    std::printf("ba_final_cost_%s=%.9g\n", k.name.c_str(), k.ours_final);
    if (have_ceres) std::printf("ceres_final_cost_%s=%.9g\n", k.name.c_str(), k.ceres_final);
  }
  for (const Keys& k : keys) {
    if (have_ceres && k.name == "ladybug49") std::printf("ba_speedup_vs_ceres=%.2f\n", k.speedup);
  }
  return 0;
}

}  // namespace

HWR_BENCH_COMMAND(ba, "ba",
                  "bundle adjustment: ours vs Ceres SPARSE_SCHUR 1 thread, time to the same final cost "
                  "(Ladybug BAL with intrinsics held fixed for both, synthetic RGB-D window; --reps=N, "
                  "--iterations=N, --huber=PX, --problem=NAME, --no-ceres)",
                  run_ba);

}  // namespace hwr::bench
