// `hwr-bench reloc` (issue #6; paper Table IV): relocalization against a prior map without a manual
// initial guess, on the simulator, per scene (lab, outdoor) and sensor set (neither, IMU/magnetometer
// only, GNSS only, both; the lab has no GNSS: those rows are "n/a (indoors)" as the paper's "\").
//
//  - Prior maps: the real pipeline, `hwr-robot --source sim:<scene> --map-out DIR --quiet` (spawned,
//    found next to this program or given with --robot), cached under --prior-cache and reused while
//    they open cleanly. The prior frame is that run's estimated world (with its drift).
//  - Starts: --starts random frames (seeded) of the revisit run (lab-revisit, outdoor-revisit: another
//    day, a plate moved, a box removed) with at least --start-walk-m of walk after them; the same
//    starts for every sensor set. A start is a robot switched on there (reloc_bench_run.hpp); its
//    relative poses over these few metres come from the simulator, not from the tracker.
//  - "Keep trying while the robot moves": the first attempt once it moved --first-motion-m, then one
//    per --attempt-step-m more, at most --max-attempts and --max-motion-m. Time to relocalize = the
//    sum of the attempts' relocalize() wall times; the motion it needed is reported too.
//  - Error of T_prior_cam at the query keyframe, (a) against the true T_prior_world
//    (T_scene_world_prior^-1 T_scene_world_start) and (b) "local": the query camera relative to the
//    nearest prior keyframe by ground truth, composed with that keyframe's stored pose -- the prior
//    map's drift taken out; (b) classifies: success <= 3 cm and 0.3 deg, false > 0.3 m or 3 deg,
//    between: inaccurate.
//  - False relocalizations: --false-starts starts of the outdoor revisit run against the lab prior
//    (outside the mapped area), without priors and with the magnetometer, every attempt up to the
//    caps; any pose returned counts.
//
//   hwr-bench reloc [--scenes lab,outdoor] [--starts 50] [--quick] [--seed 1] [--prior-cache DIR]
//                   [--robot PATH] [--false-starts 20] [--max-attempts 30] [--first-motion-m 1]
//                   [--attempt-step-m 1] [--max-motion-m 30] [--keyframe-step 12] [--verbose]
//                   [--sets neither,imu,gnss,both] [--orb-refine all|weak|off] [--start-frames F,F,...]
//                   [--min-attempt-structure N] [--min-structure N] [--start-walk-m 8.5]
//                   [--matching exact|lsh] [--targets whole|gathered] [--near-rivals keypoints|as-is]
//                   [--confirm all|weak|off] [--confirm-separation-m M]
//  --start-frames: these revisit frames instead of --starts random ones, in every scene of --scenes
//    (to rerun the starts a verbose log names: --scenes outdoor --start-frames f4678); frames past a
//    scene's last usable start are refused before its prior is opened. The false check (outdoor
//    queries vs the lab prior) then uses the first --false-starts of them.

#include "sample_stats.hpp"
#include "bench_command.hpp"

#if HWR_WITH_SIM
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <map>
#include <memory>
#include <numeric>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "reloc_bench_run.hpp"
#include "hwr/recon/prior_map.hpp"
#include "hwr/recon/relocalization_confirmation.hpp"
#include "hwr/recon/relocalization_priors.hpp"
#include "hwr/recon/relocalization_worker.hpp"
#include "hwr/recon/relocalizer.hpp"
#include "hwr/sim/scenario.hpp"

namespace hwr::bench {
namespace {

namespace fs = std::filesystem;
constexpr double kDeg = M_PI / 180.0;
constexpr int kMaxFeatures = 800;

struct Options {
  std::vector<std::string> scenes = {"lab", "outdoor"};
  int starts = 50;
  int false_starts = 20;
  std::vector<size_t> start_frames;  // --start-frames: instead of random starts
  uint64_t seed = 1;
  std::string prior_cache = "/tmp/hwr-bench-reloc-priors";
  std::string robot;
  // 30 m: outdoors the walk crosses 15-30 m of open yard between structures, where no attempt can
  // succeed (RelocalizerConfig::min_attempt_structure_points); the paper's 12.6-16.2 s outdoors are
  // ~11-15 m at the simulator's 0.9 m/s. Until 2026-12-02: 8 attempts / 8 m.
  int max_attempts = 30;
  double first_motion_m = 1.0, attempt_step_m = 1.0, max_motion_m = 30.0;
  // A start has at least this much walk after it (the same starts as with the 8 m cap before; a
  // start nearer the end has fewer attempts, as a robot whose run ends).
  double start_walk_m = 8.5;
  size_t keyframe_step = 12;
  bool verbose = false;
  std::vector<std::string> sets = {"neither", "imu", "gnss", "both"};  // rows to run (set_key)
  // Step d' (relocalizer.hpp): all (the default: degenerate and converged fine fits), weak (degenerate
  // only), off.
  std::string orb_refine = "all";
  int min_attempt_structure = -1;  // --min-attempt-structure: RelocalizerConfig's (-1: its default)
  int min_structure = -1;          // --min-structure: RelocalizerConfig::min_structure_points (-1: default)
  std::string matching = "exact";  // --matching exact|lsh (RelocalizerConfig::exact_matching)
  // --targets whole|gathered: the whole prior's NDT targets built once (RelocalizerConfig::
  // whole_prior_targets, the default) or the prior points gathered and voxelised per hypothesis.
  std::string targets = "whole";
  // --near-rivals keypoints|as-is: the geometric rivals near a weak fit judged by its keypoints
  // (RelocalizerConfig::orb_judges_near_rivals, the default) or scored as they are.
  std::string near_rivals = "keypoints";
  // --confirm all|weak|off: a weak fit without a position prior and (all) a fit whose ORB polish was
  // refused are accepted only when a later attempt agrees (relocalization_confirmation.hpp, as the
  // robot's worker does), or (off) at once.
  std::string confirm = "all";
  double confirm_separation_m = -1;  // < 0: RelocalizationConfirmationConfig's default
};

// ---- sensor sets (paper Table IV columns) ----

enum class SensorSet { kNeither, kImu, kGnss, kBoth };
constexpr SensorSet kAllSets[] = {SensorSet::kNeither, SensorSet::kImu, SensorSet::kGnss, SensorSet::kBoth};
const char* set_key(SensorSet s) {
  switch (s) {
    case SensorSet::kNeither:
      return "neither";
    case SensorSet::kImu:
      return "imu";
    case SensorSet::kGnss:
      return "gnss";
    case SensorSet::kBoth:
      return "both";
  }
  return "?";
}
const char* set_label(SensorSet s) {
  switch (s) {
    case SensorSet::kNeither:
      return "neither";
    case SensorSet::kImu:
      return "IMU/mag only";
    case SensorSet::kGnss:
      return "GNSS only";
    case SensorSet::kBoth:
      return "GNSS + IMU";
  }
  return "?";
}
bool uses_mag(SensorSet s) { return s == SensorSet::kImu || s == SensorSet::kBoth; }
bool uses_gnss(SensorSet s) { return s == SensorSet::kGnss || s == SensorSet::kBoth; }
// Paper Table IV, mean +- sd seconds; NaN: no figure ("\" or no such column).
struct PaperFigure {
  double mean_s, sd_s;
};
PaperFigure paper_figure(const std::string& scene, SensorSet s) {
  const double nan = std::nan("");
  if (scene == "outdoor") {
    if (s == SensorSet::kGnss) return {12.64, 2.83};
    if (s == SensorSet::kImu) return {16.24, 2.68};
    if (s == SensorSet::kBoth) return {1.57, 0.67};
  }
  if (scene == "lab" && s == SensorSet::kImu) return {15.37, 2.39};
  return {nan, nan};
}

// ---- prior maps ----

struct Prior {
  std::string scene, dir;
  std::unique_ptr<recon::PriorMap> map;
  Eigen::Isometry3d T_imu_cam = Eigen::Isometry3d::Identity();
  bool T_imu_cam_from_sim = false;
  Eigen::Isometry3d T_scene_prior = Eigen::Isometry3d::Identity();  // the prior run's world in the scene
  std::vector<Eigen::Isometry3d> T_prior_cam_true;                  // per prior keyframe (truth, prior run)
  std::vector<Eigen::Vector3d> p_true_m;                            // ... their positions
  double index_s = 0, open_s = 0, build_s = 0;
};

std::string default_robot_path() {
  std::error_code ec;
  const fs::path self = fs::read_symlink("/proc/self/exe", ec);
  if (ec) return "hwr-robot";
  return (self.parent_path().parent_path() / "apps" / "hwr-robot" / "hwr-robot").string();
}

core::Status run_robot(const std::string& robot, const std::string& scene, const std::string& dir) {
  std::vector<std::string> args = {robot, "--source", "sim:" + scene, "--map-out", dir, "--quiet"};
  std::fprintf(stderr, "reloc: building the %s prior map: %s --source sim:%s --map-out %s --quiet\n",
               scene.c_str(), robot.c_str(), scene.c_str(), dir.c_str());
  const pid_t pid = ::fork();
  if (pid < 0) return core::IoError("reloc: fork failed: " + std::string(std::strerror(errno)));
  if (pid == 0) {
    std::vector<char*> argv;
    for (std::string& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    ::execv(robot.c_str(), argv.data());
    std::fprintf(stderr, "reloc: cannot run %s: %s (give --robot PATH)\n", robot.c_str(),
                 std::strerror(errno));
    ::_exit(127);
  }
  int status = 0;
  if (::waitpid(pid, &status, 0) < 0) return core::IoError("reloc: waitpid failed");
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) {
    return core::Internal("reloc: " + robot + " --source sim:" + scene + " failed (status " +
                          std::to_string(WIFEXITED(status) ? WEXITSTATUS(status) : -1) + ")");
  }
  return core::Status::Ok();
}

core::Expected<Prior> open_prior(const Options& o, const std::string& scene, const RelocSimRun& prior_run) {
  Prior p;
  p.scene = scene;
  p.dir = o.prior_cache + "/" + scene;
  const auto t0 = std::chrono::steady_clock::now();
  if (!fs::exists(p.dir + "/store.yaml")) {
    std::error_code ec;
    fs::create_directories(o.prior_cache, ec);
    const std::string tmp = p.dir + ".tmp-" + std::to_string(::getpid());
    fs::remove_all(tmp, ec);
    HWR_RETURN_IF_ERROR(run_robot(o.robot.empty() ? default_robot_path() : o.robot, scene, tmp));
    fs::rename(tmp, p.dir, ec);
    if (ec) return core::IoError("reloc: cannot rename " + tmp + " to " + p.dir + ": " + ec.message());
  }
  p.build_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const auto t1 = std::chrono::steady_clock::now();
  auto map = recon::PriorMap::open(p.dir);
  if (!map.ok()) {
    return core::Status(map.status().code(), map.status().message() + " (the cached prior map " + p.dir +
                                                 " does not open: remove it to rebuild, or give another "
                                                 "--prior-cache)");
  }
  p.map = std::make_unique<recon::PriorMap>(std::move(map).value());
  p.open_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t1).count();
  p.T_imu_cam = p.map->metadata().T_imu_cam;
  if (!p.map->metadata().T_imu_cam_recorded ||
      (p.T_imu_cam.matrix() - prior_run.T_imu_cam().matrix()).cwiseAbs().maxCoeff() > 1e-6) {
    // A store without T_imu_cam, or with another one (an identity, written by an hwr-robot that had
    // the field but did not fill it in; a wrong mount turns the magnetometer heading by tens of
    // degrees): the simulator's mount is the truth.
    p.T_imu_cam = prior_run.T_imu_cam();
    p.T_imu_cam_from_sim = true;
  }
  // Truth of the prior keyframes: the prior run's ground truth at their image times.
  p.T_scene_prior = prior_run.live().calibration.T_scene_world;
  const auto& ft = prior_run.live().log.frame_t_ns;
  for (const recon::PriorKeyframe& kf : p.map->keyframes()) {
    auto it = std::lower_bound(ft.begin(), ft.end(), kf.t_ns);
    if (it == ft.end()) it = ft.end() - 1;
    if (it != ft.begin() && kf.t_ns - *(it - 1) < *it - kf.t_ns) --it;
    const size_t i = static_cast<size_t>(it - ft.begin());
    p.T_prior_cam_true.push_back(prior_run.live().groundtruth_T_world_cam_at_frames[i].T_world_body);
    p.p_true_m.push_back(p.T_prior_cam_true.back().translation());
  }
  return p;
}

// ---- errors ----

struct PoseError {
  double cm = 0, deg = 0;
};
PoseError pose_error(const Eigen::Isometry3d& estimate, const Eigen::Isometry3d& truth) {
  const Eigen::Isometry3d d = truth.inverse() * estimate;
  return {100.0 * d.translation().norm(), Eigen::AngleAxisd(d.linear()).angle() / kDeg};
}

enum class Outcome { kSuccess, kInaccurate, kFalse, kNotLocalized };
Outcome classify(bool localized, const PoseError& e) {
  if (!localized) return Outcome::kNotLocalized;
  if (e.cm <= 3.0 && e.deg <= 0.3) return Outcome::kSuccess;
  if (e.cm > 30.0 || e.deg > 3.0) return Outcome::kFalse;
  return Outcome::kInaccurate;
}

// ---- one row's record ----

struct StartRecord {
  Outcome outcome = Outcome::kNotLocalized;
  double time_s = 0;  // sum of the attempts' wall times until localized (or all of them)
  int attempts = 0;
  double moved_m = 0;
  PoseError err_true, err_local;
  std::string last_reason;
  // Fits held for confirmation (relocalization_confirmation.hpp: weak without a position prior, or
  // polish refused), and those beyond 30 cm / 3 deg of the local truth: each of these would have been
  // a false relocalization accepted at once.
  int pending_fits = 0, pending_wrong = 0;
};

struct Row {
  std::string scene;
  SensorSet set = SensorSet::kNeither;
  bool applicable = true;
  bool skipped = false;  // not in --sets
  std::vector<StartRecord> starts;
  std::map<std::string, int> attempt_reasons;  // every attempt's reason
  std::map<std::string, int> prior_notes;      // what the priors were at the first attempt
};

double median(std::vector<double> v) {
  if (v.empty()) return std::nan("");
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}
double mean(const std::vector<double>& v) {
  return v.empty() ? std::nan("") : std::accumulate(v.begin(), v.end(), 0.0) / static_cast<double>(v.size());
}

// ---- the attempts of one start against one prior, for several sensor sets ----

struct SetState {
  SensorSet set;
  recon::PriorSensorFrames frames;
  std::unique_ptr<recon::CurrentSensorPriors> priors;
  int64_t fed_until_ns = 0;
  bool done = false;
  StartRecord rec;
  recon::RelocalizationConfirmation confirm;
};

recon::RelocalizationPriorsConfig priors_config(const RelocSimRun& run, SensorSet set) {
  const sim::SimCalibration& c = run.live().calibration;
  recon::RelocalizationPriorsConfig p;
  p.use_mag = uses_mag(set);
  p.use_gnss = uses_gnss(set);
  if (c.gnss_enabled) {
    p.sigma_h_m = c.gnss_sigma_h_m > 0 ? c.gnss_sigma_h_m : 1.0;
    p.sigma_v_m = c.gnss_sigma_v_m > 0 ? c.gnss_sigma_v_m : 2.0;
    p.antenna_imu_m = c.gnss_antenna_imu_m;
  }
  p.mag.hard_iron_imu_uT = c.mag_hard_iron_uT;
  if (c.mag_noise_sigma_uT > 0) p.mag.noise_sigma_uT = c.mag_noise_sigma_uT;
  return p;
}

// The truth of T_prior_cam at a query: (a) through the scene, (b) local to the nearest prior keyframe.
struct QueryTruth {
  Eigen::Isometry3d T_prior_cam_true, T_prior_cam_local;
  // The same local truth from the nearest prior keyframe of another pass (index more than 30 away,
  // within 3 m), when there is one: how far the prior map's passes disagree there (verbose).
  bool other_pass = false;
  Eigen::Isometry3d T_prior_cam_local_other_pass = Eigen::Isometry3d::Identity();
};
QueryTruth query_truth(const Prior& prior, const RelocStart& start, const Eigen::Isometry3d& T_start_cam) {
  QueryTruth q;
  const Eigen::Isometry3d T_prior_start = prior.T_scene_prior.inverse() * start.T_scene_start();
  q.T_prior_cam_true = T_prior_start * T_start_cam;
  size_t best = 0;
  double best_d = 1e300;
  for (size_t k = 0; k < prior.p_true_m.size(); ++k) {
    const double d = (prior.p_true_m[k] - q.T_prior_cam_true.translation()).squaredNorm();
    if (d < best_d) {
      best_d = d;
      best = k;
    }
  }
  const Eigen::Isometry3d T_kf_cam = prior.T_prior_cam_true[best].inverse() * q.T_prior_cam_true;
  q.T_prior_cam_local = prior.map->keyframes()[best].T_prior_cam * T_kf_cam;
  size_t other = 0;
  double other_d = 9.0;  // (3 m)^2
  for (size_t k = 0; k < prior.p_true_m.size(); ++k) {
    if (k + 30 > best && k < best + 30) continue;
    const double d = (prior.p_true_m[k] - q.T_prior_cam_true.translation()).squaredNorm();
    if (d < other_d) {
      other_d = d;
      other = k;
      q.other_pass = true;
    }
  }
  if (q.other_pass) {
    q.T_prior_cam_local_other_pass = prior.map->keyframes()[other].T_prior_cam *
                                     (prior.T_prior_cam_true[other].inverse() * q.T_prior_cam_true);
  }
  return q;
}

// Runs the attempts of `start` for every state until each is localized or the caps are reached.
// all_attempts: keep trying after a pose (the false-relocalization check: any pose counts).
core::Status run_start(const Options& o, Prior* prior, recon::Relocalizer* reloc, RelocStart* start,
                       const Eigen::Vector3d& antenna_imu_m, std::vector<SetState>* states, Row** rows,
                       std::vector<recon::CloudPoint>* local) {
  for (int a = 0; a < o.max_attempts; ++a) {
    const double need_m = o.first_motion_m + a * o.attempt_step_m;
    if (need_m > o.max_motion_m + 1e-9) break;
    bool any = false;
    for (const SetState& s : *states) any = any || !s.done;
    if (!any) break;
    auto k = start->keyframe_at_motion(need_m);
    if (!k.ok()) return k.status();
    if (*k < 0) break;  // the run ended
    const RelocKeyframe& kf = start->keyframe(*k);
    const Eigen::Isometry3d T_world_cam = start->T_start_cam(*k);
    start->local_map(*k, T_world_cam.translation(), recon::RelocalizationWorkerConfig{}, local);
    const QueryTruth truth = query_truth(*prior, *start, T_world_cam);
    for (size_t si = 0; si < states->size(); ++si) {
      SetState& s = (*states)[si];
      if (s.done) continue;
      start->feed(kf.t_ns, antenna_imu_m, s.priors.get(), &s.fed_until_ns);
      recon::RelocalizationQuery q;
      q.features = &kf.features;
      q.T_world_cam = T_world_cam;
      if (local->empty()) continue;  // no local map yet: nothing to align
      q.local_map_world = {&(*local)[0].x_m, static_cast<int>(local->size()), 4};
      q.moved_m = start->moved_at(*k);
      const std::string note = s.priors->fill(s.frames, T_world_cam, &q);
      if (a == 0) {
        const std::string key = std::string(q.yaw_valid ? "yaw" : "no yaw") + " + " +
                                (q.position.valid ? "position" : "no position");
        ++rows[si]->prior_notes[key];
      }
      const recon::RelocalizationResult r = reloc->relocalize(q, prior->map.get());
      const recon::ConfirmationVerdict verdict = s.confirm.offer(r, q);
      ++rows[si]->attempt_reasons[recon::relocalization_reason_name(r.reason)];
      s.rec.time_s += r.wall_s;
      s.rec.attempts = a + 1;
      s.rec.moved_m = q.moved_m;
      s.rec.last_reason = recon::relocalization_reason_name(r.reason);
      if (o.verbose) {
        std::printf("    start f%zu %-8s attempt %d moved %.2f m %zu kf %zu pts: %s %.3f s | %s | %s\n",
                    start->first_frame(), set_key(s.set), a + 1, q.moved_m, static_cast<size_t>(*k + 1),
                    local->size(), r.localized ? "LOCALIZED" : "not localized", r.wall_s, note.c_str(),
                    r.message.c_str());
        const recon::RelocalizationCounters& n = r.counters;
        std::printf(
            "      stages: appearance %.3f s (index %.3f), geometry %.3f s, NDT %.3f s; %d candidates, "
            "%d ranked, %d RANSAC hypotheses, %d seeds, %d NDT runs (%d from rival seeds), "
            "%d ORB rival keyframes (%d rivals, %d near rivals refuted), target <= %lld points, %d structure "
            "points\n"
            "      NDT and acceptance: coarse %.3f s, fine %.3f s, verify %.3f s, rivals %.3f s, margin %.3f "
            "s, "
            "polish %.3f s\n",
            r.appearance_s, r.index_s, r.geometry_s, r.ndt_s, n.candidates, n.appearance_ranked,
            n.ransac_hypotheses, n.fallback_seeds, n.ndt_runs, n.rival_seeds, n.orb_rival_tests, n.orb_rivals,
            n.rivals_refuted_by_orb, static_cast<long long>(n.target_points), r.structure_points, r.coarse_s,
            r.fine_s, r.verify_s, r.rivals_s, r.margin_s, r.polish_s);
      }
      if (o.verbose && !r.localized && r.best_fit_valid) {
        // The rejected best fit: was the rejection right?
        const PoseError e = pose_error(r.T_prior_world_best_fit * T_world_cam, truth.T_prior_cam_local);
        const Outcome c = classify(true, e);
        const Eigen::Vector3d p_fit = (r.T_prior_world_best_fit * T_world_cam).translation();
        const Eigen::Vector3d p_true = truth.T_prior_cam_local.translation();
        std::printf(
            "      rejected fit: error local %.2f cm %.3f deg (%s); camera at %.1f %.1f, truth %.1f %.1f",
            e.cm, e.deg,
            c == Outcome::kSuccess      ? "correct"
            : c == Outcome::kInaccurate ? "inaccurate"
                                        : "wrong",
            p_fit.x(), p_fit.y(), p_true.x(), p_true.y());
        if (q.position.valid)
          std::printf(", position prior %.1f %.1f", q.position.p_prior_m.x(), q.position.p_prior_m.y());
        std::printf("\n");
      }
      if (o.verbose && r.best_fit_valid && r.orb_refined) {
        // Step d' replaced the NDT fit: how far off was NDT alone?
        const PoseError e = pose_error(r.T_prior_world_ndt * T_world_cam, truth.T_prior_cam_local);
        const Eigen::Isometry3d& T_fit = r.localized ? r.T_prior_world : r.T_prior_world_best_fit;
        const PoseError e_fit = pose_error(T_fit * T_world_cam, truth.T_prior_cam_local);
        std::printf(
            "      ORB-refined fit: error local %.2f cm %.3f deg; the %s NDT fit's %.2f cm %.3f deg\n",
            e_fit.cm, e_fit.deg, r.orb_refined_weak ? "degenerate" : "converged", e.cm, e.deg);
      }
      if (r.localized && verdict == recon::ConfirmationVerdict::kPending) {
        const PoseError e = pose_error(r.T_prior_world * T_world_cam, truth.T_prior_cam_local);
        ++s.rec.pending_fits;
        if (classify(true, e) == Outcome::kFalse) ++s.rec.pending_wrong;
        if (o.verbose) {
          std::printf("      pending confirmation (%s): error local %.2f cm %.3f deg\n",
                      r.polish_refused ? "its ORB polish was refused" : "a weak fit without a position prior",
                      e.cm, e.deg);
        }
      }
      if (verdict == recon::ConfirmationVerdict::kAccepted) {
        const Eigen::Isometry3d T_prior_cam = s.confirm.accepted_T_prior_world() * T_world_cam;
        s.rec.err_true = pose_error(T_prior_cam, truth.T_prior_cam_true);
        s.rec.err_local = pose_error(T_prior_cam, truth.T_prior_cam_local);
        s.rec.outcome = classify(true, s.rec.err_local);
        s.done = true;
        if (o.verbose) {
          std::printf("      error local %.2f cm %.3f deg, vs true T_prior_world %.2f cm %.3f deg",
                      s.rec.err_local.cm, s.rec.err_local.deg, s.rec.err_true.cm, s.rec.err_true.deg);
          if (truth.other_pass) {
            const PoseError e_other = pose_error(T_prior_cam, truth.T_prior_cam_local_other_pass);
            const PoseError spread = pose_error(truth.T_prior_cam_local_other_pass, truth.T_prior_cam_local);
            std::printf(
                "; another pass's keyframe: error %.2f cm %.3f deg (the passes disagree by %.2f cm %.3f deg)",
                e_other.cm, e_other.deg, spread.cm, spread.deg);
          }
          // Why an ORB refinement or the polish was refused, also when the fit was accepted.
          if (!r.orb_refine_failure.empty())
            std::printf("; ORB refinement: %s", r.orb_refine_failure.c_str());
          std::printf("\n");
        }
      }
    }
  }
  return core::Status::Ok();
}

// The last frame from which need_m of path remain.
size_t last_start(const RelocSimRun& run, double need_m) {
  size_t last = 0;
  const double total = run.path_at_frame_m(run.frames() - 1);
  while (last + 1 < run.frames() && run.path_at_frame_m(last + 1) <= total - need_m) ++last;
  return last;
}

std::vector<size_t> draw_starts(const RelocSimRun& run, int n, double need_m, std::mt19937_64* rng) {
  std::uniform_int_distribution<size_t> pick(0, last_start(run, need_m));
  std::vector<size_t> out;
  for (int i = 0; i < n; ++i) out.push_back(pick(*rng));
  return out;
}

std::string fmt_time(const std::vector<double>& t) {
  if (t.empty()) return "-";
  char buf[96];
  std::snprintf(buf, sizeof(buf), "%.3f / %.3f +- %.3f", median(t), mean(t), sample_sd(t));
  return buf;
}

int run_reloc(int argc, char** argv) {
  Options o;
  bool starts_given = false, false_given = false, quick = false;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&](const char* name) -> std::string {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "reloc: %s needs a value\n", name);
        std::exit(2);
      }
      return argv[++i];
    };
    if (a == "--scenes") {
      o.scenes.clear();
      std::stringstream ss(value("--scenes"));
      for (std::string s; std::getline(ss, s, ',');) {
        if (s != "lab" && s != "outdoor") {
          std::fprintf(stderr, "reloc: unknown scene '%s' (lab, outdoor)\n", s.c_str());
          return 2;
        }
        o.scenes.push_back(s);
      }
    } else if (a == "--starts") {
      o.starts = std::atoi(value("--starts").c_str());
      starts_given = true;
    } else if (a == "--false-starts") {
      o.false_starts = std::atoi(value("--false-starts").c_str());
      false_given = true;
    } else if (a == "--quick") {
      quick = true;
    } else if (a == "--seed") {
      o.seed = std::strtoull(value("--seed").c_str(), nullptr, 10);
    } else if (a == "--prior-cache") {
      o.prior_cache = value("--prior-cache");
    } else if (a == "--robot") {
      o.robot = value("--robot");
    } else if (a == "--max-attempts") {
      o.max_attempts = std::atoi(value("--max-attempts").c_str());
    } else if (a == "--first-motion-m") {
      o.first_motion_m = std::atof(value("--first-motion-m").c_str());
    } else if (a == "--attempt-step-m") {
      o.attempt_step_m = std::atof(value("--attempt-step-m").c_str());
    } else if (a == "--start-walk-m") {
      o.start_walk_m = std::atof(value("--start-walk-m").c_str());
    } else if (a == "--max-motion-m") {
      o.max_motion_m = std::atof(value("--max-motion-m").c_str());
    } else if (a == "--keyframe-step") {
      o.keyframe_step = static_cast<size_t>(std::max(1, std::atoi(value("--keyframe-step").c_str())));
    } else if (a == "--verbose") {
      o.verbose = true;
    } else if (a == "--matching") {
      o.matching = value("--matching");
      if (o.matching != "exact" && o.matching != "lsh") {
        std::fprintf(stderr, "reloc: --matching takes exact or lsh\n");
        return 2;
      }
    } else if (a == "--targets") {
      o.targets = value("--targets");
      if (o.targets != "whole" && o.targets != "gathered") {
        std::fprintf(stderr, "reloc: --targets takes whole or gathered\n");
        return 2;
      }
    } else if (a == "--near-rivals") {
      o.near_rivals = value("--near-rivals");
      if (o.near_rivals != "keypoints" && o.near_rivals != "as-is") {
        std::fprintf(stderr, "reloc: --near-rivals takes keypoints or as-is\n");
        return 2;
      }
    } else if (a == "--confirm") {
      o.confirm = value("--confirm");
      if (o.confirm != "all" && o.confirm != "weak" && o.confirm != "off") {
        std::fprintf(stderr, "reloc: --confirm takes all, weak or off\n");
        return 2;
      }
    } else if (a == "--confirm-separation-m") {
      o.confirm_separation_m = std::atof(value("--confirm-separation-m").c_str());
      if (!(o.confirm_separation_m >= 0)) {
        std::fprintf(stderr, "reloc: --confirm-separation-m takes metres >= 0\n");
        return 2;
      }
    } else if (a == "--min-attempt-structure") {
      o.min_attempt_structure = std::atoi(value("--min-attempt-structure").c_str());
    } else if (a == "--min-structure") {
      o.min_structure = std::atoi(value("--min-structure").c_str());
    } else if (a == "--orb-refine") {
      o.orb_refine = value("--orb-refine");
      if (o.orb_refine != "off" && o.orb_refine != "weak" && o.orb_refine != "all") {
        std::fprintf(stderr, "reloc: --orb-refine takes all, weak or off\n");
        return 2;
      }
    } else if (a == "--start-frames") {
      std::stringstream ss(value("--start-frames"));
      for (std::string f; std::getline(ss, f, ',');) {
        const std::string digits = !f.empty() && f[0] == 'f' ? f.substr(1) : f;
        if (digits.empty() || digits.size() > 9 ||
            !std::all_of(digits.begin(), digits.end(), [](char ch) { return ch >= '0' && ch <= '9'; })) {
          std::fprintf(stderr, "reloc: --start-frames takes frame numbers (f4678 or 4678), got '%s'\n",
                       f.c_str());
          return 2;
        }
        o.start_frames.push_back(static_cast<size_t>(std::stoul(digits)));
      }
    } else if (a == "--sets") {
      o.sets.clear();
      std::stringstream ss(value("--sets"));
      for (std::string s; std::getline(ss, s, ',');) {
        if (s != "neither" && s != "imu" && s != "gnss" && s != "both") {
          std::fprintf(stderr, "reloc: unknown sensor set '%s' (neither, imu, gnss, both)\n", s.c_str());
          return 2;
        }
        o.sets.push_back(s);
      }
    } else {
      std::fprintf(
          stderr,
          "usage: hwr-bench reloc [--scenes lab,outdoor] [--starts N] [--quick] [--seed S]\n"
          "       [--prior-cache DIR] [--robot PATH] [--false-starts N] [--max-attempts N]\n"
          "       [--first-motion-m M] [--attempt-step-m M] [--max-motion-m M] [--keyframe-step N] "
          "[--verbose]\n       [--sets neither,imu,gnss,both] [--orb-refine all|weak|off] "
          "[--start-frames F,F,...]\n"
          "       [--min-attempt-structure N] [--min-structure N] [--start-walk-m M]\n"
          "       [--matching exact|lsh] [--targets whole|gathered] [--near-rivals keypoints|as-is]\n"
          "       [--confirm all|weak|off] [--confirm-separation-m M]\n");
      return a == "--help" || a == "-h" ? 0 : 2;
    }
  }
  if (quick) {
    if (!starts_given) o.starts = 10;
    if (!false_given) o.false_starts = 5;
  }
  if (o.starts < 1 || o.false_starts < 0 || o.max_attempts < 1 || !(o.first_motion_m > 0) ||
      !(o.attempt_step_m > 0) || !(o.max_motion_m >= o.first_motion_m) || !(o.start_walk_m >= 0)) {
    std::fprintf(stderr,
                 "reloc: need --starts >= 1, --false-starts >= 0, --max-attempts >= 1, motions > 0, "
                 "--max-motion-m >= --first-motion-m, --start-walk-m >= 0\n");
    return 2;
  }
  const auto t_bench = std::chrono::steady_clock::now();
  recon::RelocalizerConfig rcfg;  // the defaults, but for --orb-refine
  rcfg.orb_refine = o.orb_refine != "off";
  rcfg.orb_refine_converged = o.orb_refine == "all";
  if (o.min_attempt_structure >= 0) rcfg.min_attempt_structure_points = o.min_attempt_structure;
  if (o.min_structure >= 0) rcfg.min_structure_points = o.min_structure;
  rcfg.exact_matching = o.matching == "exact";
  rcfg.whole_prior_targets = o.targets == "whole";
  rcfg.orb_judges_near_rivals = o.near_rivals == "keypoints";
  recon::RelocalizationConfirmationConfig confirm_cfg;
  confirm_cfg.confirm_weak_without_position = o.confirm != "off";
  confirm_cfg.confirm_unpolished = o.confirm == "all";
  if (o.confirm_separation_m >= 0) confirm_cfg.min_separation_m = o.confirm_separation_m;
  std::printf(
      "hwr-bench reloc: %d starts per scene (seed %llu), %d false starts (outdoor vs lab prior); attempts "
      "from %.1f m "
      "every %.1f m, at most %d / %.1f m; keyframes every %zu frames while moving\n",
      o.start_frames.empty() ? o.starts : static_cast<int>(o.start_frames.size()),
      static_cast<unsigned long long>(o.seed), o.false_starts, o.first_motion_m, o.attempt_step_m,
      o.max_attempts, o.max_motion_m, o.keyframe_step);
  std::printf(
      "relocalizer: RelocalizerConfig defaults (top_k %d, min_votes %d, keep_best %d, min_inlier_ratio "
      "%.2f, min_score_margin %.2f, candidate_sigma_factor %.1f, ndt_fine down to %.2f m, attempts need %d "
      "structure points, %s "
      "keyframe matching), ORB refinement %s, near rivals of weak fits %s, weak fits without a position "
      "prior%s %s (its camera >= %.1f m from the held fit's)\n",
      rcfg.top_k, rcfg.min_votes, rcfg.keep_best, rcfg.min_inlier_ratio, rcfg.min_score_margin,
      rcfg.candidate_sigma_factor, rcfg.ndt_fine.resolutions_m[1], rcfg.min_attempt_structure_points,
      o.matching.c_str(), o.orb_refine.c_str(),
      o.near_rivals == "keypoints" ? "judged by keypoints" : "as they are",
      o.confirm == "all" ? " and fits with a refused polish" : "",
      o.confirm != "off" ? "confirmed by a later attempt" : "accepted at once", confirm_cfg.min_separation_m);

  struct Scene {
    std::string name;
    std::unique_ptr<RelocSimRun> revisit;
    std::unique_ptr<Prior> prior;
    std::unique_ptr<recon::Relocalizer> reloc;
    std::vector<std::unique_ptr<RelocStart>> starts;
  };
  std::vector<Scene> scenes;
  std::mt19937_64 rng(o.seed);
  for (const std::string& name : o.scenes) {
    Scene sc;
    sc.name = name;
    std::fprintf(stderr, "reloc: %s: opening the prior run's truth and the revisit run\n", name.c_str());
    auto prior_run = RelocSimRun::open(name, kMaxFeatures);
    if (!prior_run.ok()) {
      std::fprintf(stderr, "reloc: %s\n", prior_run.status().message().c_str());
      return 1;
    }
    auto revisit = RelocSimRun::open(name + "-revisit", kMaxFeatures);
    if (!revisit.ok()) {
      std::fprintf(stderr, "reloc: %s\n", revisit.status().message().c_str());
      return 1;
    }
    sc.revisit = std::move(revisit).value();
    // Chosen starts are checked before the prior map is opened (or built: minutes).
    const size_t last = last_start(*sc.revisit, o.start_walk_m);
    for (size_t f : o.start_frames) {
      if (f > last) {
        std::fprintf(stderr, "reloc: %s: start frame %zu is past the last usable start (f%zu)\n",
                     name.c_str(), f, last);
        return 2;
      }
    }
    auto prior = open_prior(o, name, **prior_run);
    if (!prior.ok()) {
      std::fprintf(stderr, "reloc: %s\n", prior.status().message().c_str());
      return 1;
    }
    sc.prior = std::make_unique<Prior>(std::move(prior).value());
    const int max_features = std::max(kMaxFeatures, sc.prior->map->max_keyframe_features());
    auto reloc = recon::Relocalizer::create(rcfg, sc.revisit->K(), max_features);
    if (!reloc.ok()) {
      std::fprintf(stderr, "reloc: %s\n", reloc.status().message().c_str());
      return 1;
    }
    sc.reloc = std::make_unique<recon::Relocalizer>(std::move(reloc).value());
    const auto t_index = std::chrono::steady_clock::now();
    sc.reloc->prepare(*sc.prior->map);
    sc.prior->index_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_index).count();
    // As RelocalizationWorker does at start: the clouds within the budget are read before any attempt.
    const auto t_preload = std::chrono::steady_clock::now();
    const recon::PreloadStats preload = sc.prior->map->preload_clouds();
    std::printf(
        "prior %s: clouds preloaded in %.2f s: %d of %zu segments, %lld points (thinned to %.2f m; "
        "%lld stored points read), %d over the budget of %lld, %d unreadable\n",
        name.c_str(), std::chrono::duration<double>(std::chrono::steady_clock::now() - t_preload).count(),
        preload.segments_in_memory, sc.prior->map->segments().size(),
        static_cast<long long>(preload.points_in_memory), sc.prior->map->config().cloud_voxel_m,
        static_cast<long long>(sc.prior->map->counters().points_read), preload.segments_over_budget,
        static_cast<long long>(sc.prior->map->config().max_loaded_points), preload.segments_unreadable);
    // As RelocalizationWorker does after the preload: the whole prior's NDT targets, once.
    const recon::Relocalizer::WholePriorTargets whole = sc.reloc->prepare_targets(*sc.prior->map);
    if (whole.built) {
      std::printf("prior %s: whole-prior NDT targets in %.2f s: %d resolutions, %lld points, %lld voxels\n",
                  name.c_str(), whole.seconds, whole.levels, static_cast<long long>(whole.points),
                  static_cast<long long>(whole.voxels));
    } else {
      std::printf("prior %s: no whole-prior NDT targets (%s): each attempt gathers its own\n", name.c_str(),
                  whole.why_not.c_str());
    }
    std::printf(
        "prior %s: %s (%zu keyframes, %zu segments; opened in %.2f s, LSH index %.2f s%s)%s\n", name.c_str(),
        sc.prior->dir.c_str(), sc.prior->map->keyframes().size(), sc.prior->map->segments().size(),
        sc.prior->open_s, sc.prior->index_s,
        sc.prior->build_s > 1.0
            ? (", built by hwr-robot in " + std::to_string(sc.prior->build_s) + " s").c_str()
            : ", cached",
        sc.prior->T_imu_cam_from_sim
            ? "; its store has no T_imu_cam or another than the simulator's: the simulator's mount is used"
            : "");
    for (size_t f :
         o.start_frames.empty() ? draw_starts(*sc.revisit, o.starts, o.start_walk_m, &rng) : o.start_frames) {
      sc.starts.push_back(std::make_unique<RelocStart>(sc.revisit.get(), f, o.keyframe_step, kMaxFeatures));
    }
    scenes.push_back(std::move(sc));
  }

  // ---- Table IV rows ----
  std::vector<std::unique_ptr<Row>> rows;
  std::vector<recon::CloudPoint> local;
  for (Scene& sc : scenes) {
    const bool has_gnss = sc.revisit->live().calibration.gnss_enabled;
    std::vector<SensorSet> sets;
    for (SensorSet s : kAllSets) {
      auto row = std::make_unique<Row>();
      row->scene = sc.name;
      row->set = s;
      row->applicable = has_gnss || !uses_gnss(s);
      row->skipped = std::find(o.sets.begin(), o.sets.end(), std::string(set_key(s))) == o.sets.end();
      if (row->applicable && !row->skipped) sets.push_back(s);
      rows.push_back(std::move(row));
    }
    std::vector<Row*> row_of;
    std::vector<SetState> states;
    for (SensorSet s : sets) {
      for (auto& r : rows) {
        if (r->scene == sc.name && r->set == s) row_of.push_back(r.get());
      }
      SetState st;
      st.set = s;
      st.confirm = recon::RelocalizationConfirmation(confirm_cfg);
      const recon::RelocalizationPriorsConfig pc = priors_config(*sc.revisit, s);
      auto frames = recon::prior_sensor_frames(*sc.prior->map, sc.prior->T_imu_cam, pc);
      if (!frames.ok()) {
        std::fprintf(stderr, "reloc: %s\n", frames.status().message().c_str());
        return 1;
      }
      st.frames = std::move(frames).value();
      st.priors = std::make_unique<recon::CurrentSensorPriors>(pc);
      if (s == SensorSet::kBoth) std::printf("prior %s: %s\n", sc.name.c_str(), st.frames.summary.c_str());
      states.push_back(std::move(st));
    }
    const auto t_scene = std::chrono::steady_clock::now();
    for (size_t i = 0; i < sc.starts.size(); ++i) {
      for (SetState& st : states) {
        st.priors->reset();
        st.fed_until_ns = 0;
        st.done = false;
        st.rec = StartRecord();
        st.confirm.reset();
      }
      const core::Status status =
          run_start(o, sc.prior.get(), sc.reloc.get(), sc.starts[i].get(),
                    sc.revisit->live().calibration.gnss_antenna_imu_m, &states, row_of.data(), &local);
      if (!status.ok()) {
        std::fprintf(stderr, "reloc: %s\n", status.message().c_str());
        return 1;
      }
      for (size_t s = 0; s < states.size(); ++s) row_of[s]->starts.push_back(states[s].rec);
      std::fprintf(stderr, "\rreloc: %s start %zu/%zu (%.0f s)", sc.name.c_str(), i + 1, sc.starts.size(),
                   std::chrono::duration<double>(std::chrono::steady_clock::now() - t_scene).count());
    }
    std::fprintf(stderr, "\n");
  }

  // ---- false relocalizations: each revisit's starts against the other scene's prior ----
  int false_reloc = 0, false_runs = 0, false_attempts = 0, false_pending = 0;
  std::map<std::string, int> false_reasons;
  if (scenes.size() == 2 && o.false_starts > 0) {
    // Outdoor queries against the lab prior (the cheaper direction: the lab prior is small).
    for (size_t qi = 0; qi < 2; ++qi) {
      if (scenes[qi].name != "outdoor") continue;
      Scene& query_scene = scenes[qi];
      Scene& prior_scene = scenes[1 - qi];
      for (SensorSet s : {SensorSet::kNeither, SensorSet::kImu}) {
        Row row;
        row.scene = query_scene.name + " vs " + prior_scene.name;
        row.set = s;
        Row* rp = &row;
        SetState st;
        st.set = s;
        st.confirm = recon::RelocalizationConfirmation(confirm_cfg);
        const recon::RelocalizationPriorsConfig pc = priors_config(*query_scene.revisit, s);
        auto frames = recon::prior_sensor_frames(*prior_scene.prior->map, prior_scene.prior->T_imu_cam, pc);
        if (!frames.ok()) return 1;
        st.frames = std::move(frames).value();
        st.priors = std::make_unique<recon::CurrentSensorPriors>(pc);
        std::vector<SetState> states;
        states.push_back(std::move(st));
        const int n = std::min<int>(o.false_starts, static_cast<int>(query_scene.starts.size()));
        int localized_here = 0;
        for (int i = 0; i < n; ++i) {
          states[0].priors->reset();
          states[0].fed_until_ns = 0;
          states[0].done = false;
          states[0].rec = StartRecord();
          states[0].confirm.reset();
          // Truth does not matter here (any pose is false); the prior's truth is the other scene's.
          const core::Status status =
              run_start(o, prior_scene.prior.get(), prior_scene.reloc.get(), query_scene.starts[i].get(),
                        query_scene.revisit->live().calibration.gnss_antenna_imu_m, &states, &rp, &local);
          if (!status.ok()) {
            std::fprintf(stderr, "reloc: %s\n", status.message().c_str());
            return 1;
          }
          ++false_runs;
          false_attempts += states[0].rec.attempts;
          false_pending += states[0].rec.pending_fits;  // weak poses never confirmed: not accepted
          if (states[0].rec.outcome != Outcome::kNotLocalized) {
            ++false_reloc;
            ++localized_here;
          }
        }
        for (const auto& [reason, count] : row.attempt_reasons) false_reasons[reason] += count;
        std::printf("false check: %s queries vs the %s prior, %s: %d starts, %d localized\n",
                    query_scene.name.c_str(), prior_scene.name.c_str(), set_label(s), n, localized_here);
      }
    }
  }

  // ---- the table ----
  std::printf(
      "\nTable IV (sim): time to relocalize = sum of relocalize() wall times of the attempts (s, compute "
      "only: "
      "the walking between attempts is in the motion column); median / mean +- sd over the successful "
      "starts, the "
      "median over all starts (a start that never localized counts as infinite) in the key lines; error (b) "
      "local "
      "to the nearest prior keyframe, (a) against the true T_prior_world; inacc: accepted with an error "
      "between "
      "3 cm / 0.3 deg and 30 cm / 3 deg, false: beyond\n");
  std::printf("%-8s %-13s %7s %6s %6s %6s %-26s %6s %7s %-19s %-19s %-17s\n", "scene", "sensors", "success",
              "inacc", "false", "notloc", "time median / mean +- sd", "tries", "motion", "err(b) med/max cm",
              "err(b) med/max deg", "paper s");
  double min_success = 1e9, max_median_nognss = 0, median_gnss_both = std::nan("");
  double err_cm_max = 0, err_deg_max = 0;
  int false_rows = 0, inaccurate_rows = 0, pending_rows = 0, pending_wrong_rows = 0;
  std::vector<std::string> keys;
  char buf[512];
  for (const auto& r : rows) {
    const PaperFigure paper = paper_figure(r->scene, r->set);
    std::string paper_text = std::isnan(paper.mean_s) ? (r->applicable ? "-" : "\\")
                                                      : std::to_string(paper.mean_s).substr(0, 5) + " +- " +
                                                            std::to_string(paper.sd_s).substr(0, 4);
    if (!r->applicable || r->skipped) {
      std::printf("%-8s %-13s %7s  %-22s%68s\n", r->scene.c_str(), set_label(r->set), "",
                  r->skipped ? "not run (--sets)" : "n/a (indoors: no GNSS)", paper_text.c_str());
      continue;
    }
    int n_success = 0, n_inacc = 0, n_false = 0, n_not = 0, n_pending = 0, n_pending_wrong = 0;
    std::vector<double> times, times_all, tries, motion, ecm, edeg, ecm_true, edeg_true;
    for (const StartRecord& s : r->starts) {
      n_pending += s.pending_fits;
      n_pending_wrong += s.pending_wrong;
      switch (s.outcome) {
        case Outcome::kSuccess:
          ++n_success;
          break;
        case Outcome::kInaccurate:
          ++n_inacc;
          break;
        case Outcome::kFalse:
          ++n_false;
          break;
        case Outcome::kNotLocalized:
          ++n_not;
          break;
      }
      times_all.push_back(s.outcome == Outcome::kSuccess ? s.time_s : HUGE_VAL);
      if (s.outcome == Outcome::kSuccess) {
        times.push_back(s.time_s);
        tries.push_back(s.attempts);
        motion.push_back(s.moved_m);
      }
      if (s.outcome != Outcome::kNotLocalized) {
        ecm.push_back(s.err_local.cm);
        edeg.push_back(s.err_local.deg);
        ecm_true.push_back(s.err_true.cm);
        edeg_true.push_back(s.err_true.deg);
      }
    }
    const double n = static_cast<double>(r->starts.size());
    const double success_pct = 100.0 * n_success / n;
    const double cm_max = ecm.empty() ? 0 : *std::max_element(ecm.begin(), ecm.end());
    const double deg_max = edeg.empty() ? 0 : *std::max_element(edeg.begin(), edeg.end());
    std::snprintf(buf, sizeof(buf), "%.2f / %.2f", ecm.empty() ? 0 : median(ecm), cm_max);
    const std::string e_cm = buf;
    std::snprintf(buf, sizeof(buf), "%.3f / %.3f", edeg.empty() ? 0 : median(edeg), deg_max);
    const std::string e_deg = buf;
    std::printf("%-8s %-13s %6.1f%% %6d %6d %6d %-26s %6.2f %6.2fm %-19s %-19s %-17s\n", r->scene.c_str(),
                set_label(r->set), success_pct, n_inacc, n_false, n_not, fmt_time(times).c_str(),
                tries.empty() ? 0 : mean(tries), motion.empty() ? 0 : median(motion), e_cm.c_str(),
                e_deg.c_str(), paper_text.c_str());
    std::printf(
        "%-22s err(a) vs true T_prior_world med/max: %.2f / %.2f cm, %.3f / %.3f deg; priors at attempt 1:",
        "", ecm_true.empty() ? 0 : median(ecm_true),
        ecm_true.empty() ? 0 : *std::max_element(ecm_true.begin(), ecm_true.end()),
        edeg_true.empty() ? 0 : median(edeg_true),
        edeg_true.empty() ? 0 : *std::max_element(edeg_true.begin(), edeg_true.end()));
    for (const auto& [k, c] : r->prior_notes) std::printf(" %s x%d;", k.c_str(), c);
    std::printf("\n%-22s attempt results:", "");
    for (const auto& [k, c] : r->attempt_reasons) std::printf(" %s %d;", k.c_str(), c);
    std::printf(
        "\n%-22s fits held for confirmation (weak without a position prior, or polish refused): %d, %d of "
        "them wrong\n",
        "", n_pending, n_pending_wrong);
    pending_rows += n_pending;
    pending_wrong_rows += n_pending_wrong;
    min_success = std::min(min_success, success_pct);
    // Over all starts: a start that never localized counts as infinitely slow.
    const double median_all = median(times_all);
    if (!uses_gnss(r->set)) max_median_nognss = std::max(max_median_nognss, median_all);
    if (r->set == SensorSet::kBoth) median_gnss_both = median_all;
    inaccurate_rows += n_inacc;
    err_cm_max = std::max(err_cm_max, cm_max);
    err_deg_max = std::max(err_deg_max, deg_max);
    false_rows += n_false;
    const std::string prefix = "reloc_" + r->scene + "_" + set_key(r->set);
    std::snprintf(buf, sizeof(buf), "%s_success_pct=%.1f", prefix.c_str(), success_pct);
    keys.push_back(buf);
    std::snprintf(buf, sizeof(buf), "%s_median_s=%.3f", prefix.c_str(), median_all);
    keys.push_back(buf);
    std::snprintf(buf, sizeof(buf), "%s_median_s_successful=%.3f", prefix.c_str(),
                  times.empty() ? std::nan("") : median(times));
    keys.push_back(buf);
    // The paper's statistic (Table IV: mean ± sd), over the successful starts.
    std::snprintf(buf, sizeof(buf), "%s_mean_s_successful=%.3f", prefix.c_str(), mean(times));
    keys.push_back(buf);
    std::snprintf(buf, sizeof(buf), "%s_sd_s_successful=%.3f", prefix.c_str(),
                  times.empty() ? std::nan("") : sample_sd(times));
    keys.push_back(buf);
    std::snprintf(buf, sizeof(buf), "%s_false=%d", prefix.c_str(), n_false);
    keys.push_back(buf);
  }
  std::printf(
      "\nfalse relocalizations: %d in the rows (error > 30 cm or 3 deg), %d of %d cross-scene starts (%d "
      "attempts, every one must say not localized; weak poses held for confirmation there: %d):",
      false_rows, false_reloc, false_runs, false_attempts, false_pending);
  for (const auto& [k, c] : false_reasons) std::printf(" %s %d;", k.c_str(), c);
  std::printf(
      "\nrender: %.1f s; whole bench %.0f s\n\n",
      [&] {
        double s = 0;
        for (const Scene& sc : scenes) s += sc.revisit->render_s();
        return s;
      }(),
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t_bench).count());

  std::printf("reloc_success_pct=%.1f\n", min_success);
  std::printf("reloc_median_s_nognss=%.3f\n", max_median_nognss);
  if (std::isnan(median_gnss_both)) {
    std::printf("reloc_median_s_gnss=nan\n");
  } else {
    std::printf("reloc_median_s_gnss=%.3f\n", median_gnss_both);
  }
  std::printf("reloc_false=%d\n", false_rows + false_reloc);
  std::printf("reloc_inaccurate=%d\n", inaccurate_rows);
  std::printf("reloc_false_cross_scene_starts=%d\n", false_runs);
  std::printf("reloc_err_cm_max=%.2f\n", err_cm_max);
  std::printf("reloc_err_deg_max=%.3f\n", err_deg_max);
  std::printf("reloc_pending_fits=%d\n", pending_rows);
  std::printf("reloc_pending_wrong=%d\n", pending_wrong_rows);
  for (const std::string& k : keys) std::printf("%s\n", k.c_str());
  return 0;
}

}  // namespace

HWR_BENCH_COMMAND(reloc, "reloc",
                  "relocalization against a prior map, paper Table IV (sim lab/outdoor x sensor sets)",
                  run_reloc);

}  // namespace hwr::bench
#endif  // HWR_WITH_SIM
