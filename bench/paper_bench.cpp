// `hwr-bench paper` (issue #9 item 3): the paper's Tables I-IV with this run's figures beside the
// paper's and the peers', from the other benches run as child processes of this one. Each sub-run is
// `hwr-bench SUB args...` (this very program, /proc/self/exe) with its stdout captured through a pipe
// and its stderr written to a log; the tables are built from the sub-runs' `key=value` lines only, so
// every cell is a figure an individual bench prints with the same arguments (each cell names its run
// and key; paper_tables.md lists the command lines to rerun them). A sub-run that fails, or whose
// dataset is absent, leaves "n/a (why)" in its cells and the command goes on.
//
//   hwr-bench paper [--out DIR] [--quick] [--skip frame,segmentation,transfer,reloc,imu,ba,ndt]
//                   [--duration S] [--run-timeout S] [--dry-run]
//
// --out: default build/paper-report where ./build exists, else ./paper-report. --quick: a smoke test
// of a few minutes (shorter sim walks, fewer starts and sizes). --duration: the simulated seconds of
// each sim walk in `frame` and `segmentation`. --dry-run: print the sub-runs' command lines only.
// Writes DIR/paper_tables.md, DIR/paper_tables.csv, DIR/trajectory_<sequence>.png, DIR/runs/<id>.stdout
// and .stderr, DIR/trajectories/*.tum. Exit code 0 when the report is written (whatever the sub-runs
// did), 1 when it cannot be, 2 for a usage error, 130 when interrupted (the report so far is written).
// docs/paper_report.md.

#include <fcntl.h>
#include <poll.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "bench_command.hpp"
#include "hwr/core/file_io.hpp"
#include "hwr/core/tum_trajectory.hpp"
#include "paper_plots.hpp"
#include "paper_tables.hpp"

extern char** environ;

namespace hwr::bench {
namespace {

namespace fs = std::filesystem;
using paper::Cell;
using paper::Row;
using paper::RunResult;
using paper::Table;

// ---- the plan ----

struct Options {
  std::string out_dir;
  bool quick = false;
  std::set<std::string> skip;
  double duration_s = 0;  // 0: the plan's
  double run_timeout_s = 900;
  bool dry_run = false;
};

struct RunSpec {
  std::string id;                  // the subcommand (one run per subcommand)
  std::vector<std::string> args;   // after the subcommand
  std::vector<std::string> needs;  // dataset paths that must exist
  std::string not_built;           // non-empty: this build cannot run it (why)
};

const std::string kData = HWR_DATA_DIR;
const std::string kTeddy = kData + "/tum-fr3-teddy-200/rgbd_dataset_freiburg3_teddy";
const char* const kAllIds[] = {"frame", "segmentation", "transfer", "reloc", "imu", "ba", "ndt"};

#if HWR_WITH_SIM
constexpr bool kHaveSim = true;
#else
constexpr bool kHaveSim = false;
#endif

// What each sub-run covers. The arguments keep the whole command within 15 minutes on the 2-core
// development host (docs/paper_report.md has the measured times); --quick within a few minutes.
struct Plan {
  std::vector<RunSpec> runs;
  std::vector<std::string> frame_sequences;  // as given to `frame`
  double sim_duration_s = 0;
  double seg_duration_s = 0;
  std::vector<std::string> sizes;  // Table II columns run by `transfer`
  int reloc_starts = 0;
};

Plan make_plan(const Options& o, const std::string& traj_dir) {
  Plan p;
  p.sim_duration_s = o.duration_s > 0 ? o.duration_s : (o.quick ? 10 : 30);
  p.seg_duration_s = o.duration_s > 0 ? o.duration_s : (o.quick ? 20 : 45);
  const auto num = [](double v) {
    char buf[32];
    std::snprintf(buf, sizeof(buf), "%g", v);
    return std::string(buf);
  };
  const bool have_teddy = fs::exists(kTeddy);
  if (have_teddy) p.frame_sequences.push_back("teddy");
  if (kHaveSim) {
    p.frame_sequences.push_back("lab");
    if (!o.quick) p.frame_sequences.push_back("outdoor");
  }
  std::string seqs;
  for (const auto& s : p.frame_sequences) seqs += (seqs.empty() ? "" : ",") + s;
  RunSpec frame{"frame",
                {"--sequences", seqs, "--duration", num(p.sim_duration_s), "--traj-out", traj_dir},
                {},
                p.frame_sequences.empty() ? "no sequence: TUM teddy absent and no simulator" : ""};
  p.runs.push_back(frame);
  const std::string no_sim = kHaveSim ? "" : "this build has no simulator (HWR_WITH_SIM=OFF)";
  p.runs.push_back({"segmentation",
                    {"--sequences", o.quick ? "lab" : "lab,outdoor", "--duration", num(p.seg_duration_s)},
                    {},
                    no_sim});
  // Table II: the paper's five map sizes over a 1 Gbit/s link (its wired network); the mapping
  // timeline of the streamed rows replayed 4x faster than simulated time (under a third of one core's
  // encode rate, as the bench's own cap), the captured point stream kept for the next run.
  p.sizes = o.quick ? std::vector<std::string>{"0.1", "0.9"}
                    : std::vector<std::string>{"0.1", "0.9", "1.7", "2.5", "3.8"};
  std::string sizes;
  for (const auto& s : p.sizes) sizes += (sizes.empty() ? "" : ",") + s;
  p.runs.push_back({"transfer",
                    {"--sequences", "lab", "--sizes", sizes, "--rates", "1000", "--time-compression", "4",
                     "--stream-cache", o.out_dir + "/transfer-point-stream.bin"},
                    {},
                    no_sim});
  // Table IV: 10 starts per scene (reloc --quick), the prior maps in reloc's default cache.
  p.reloc_starts = o.quick ? 3 : 10;
  if (o.quick) {
    p.runs.push_back(
        {"reloc", {"--quick", "--scenes", "lab", "--starts", "3", "--false-starts", "0"}, {}, no_sim});
  } else {
    p.runs.push_back({"reloc", {"--quick"}, {}, no_sim});
  }
  p.runs.push_back(
      {"imu", {}, {kData + "/euroc-v1-01-static-start/mav0", kData + "/euroc-v1-02-imu-40s/mav0"}, ""});
  // Every problem with the bench's defaults (~40 s); its lab_full_30s needs the simulator.
  std::vector<std::string> ba_args;
  if (o.quick) {
    ba_args = {"--reps=1", "--problem=ladybug49_1800"};
  } else if (!kHaveSim) {
    ba_args = {"--problem=ladybug49"};
  }
  p.runs.push_back({"ba", ba_args, {kData + "/bal-ladybug", kTeddy}, ""});
  p.runs.push_back(
      {"ndt",
       {"--quick"},
       {kData + "/lidar-scan-pair", kData + "/car-scans/examples/data", kData + "/pcl-scans/tutorials"},
       no_sim});
  return p;
}

// ---- child processes ----

volatile std::sig_atomic_t g_interrupted = 0;
extern "C" void on_interrupt(int) { g_interrupted = 1; }

std::string self_exe() {
  std::error_code ec;
  const fs::path p = fs::read_symlink("/proc/self/exe", ec);
  return ec ? std::string() : p.string();
}

std::string shell_quote(const std::string& s) {
  if (!s.empty() &&
      s.find_first_not_of("ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789_./,:=+-") ==
          std::string::npos)
    return s;
  std::string out = "'";
  for (char c : s) out += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return out + "'";
}

std::string command_line(const std::vector<std::string>& argv) {
  std::string s;
  for (const auto& a : argv) s += (s.empty() ? "" : " ") + shell_quote(a);
  return s;
}

void kill_group(pid_t pgid, int sig) {
  if (pgid > 0) ::kill(-pgid, sig);
}

// Runs this program with argv (argv[0] only names it) in its own process group (so a timeout or an
// interrupt ends whatever it started too), stdout into *out and stdout_path, stderr into stderr_path.
struct ChildResult {
  bool started = false;
  std::string error;
  int exit_code = -1;
  int signal = 0;
  bool timed_out = false;
  bool interrupted = false;
  double wall_s = 0;
};

ChildResult run_child(const std::vector<std::string>& argv, const std::string& stdout_path,
                      const std::string& stderr_path, double timeout_s, std::string* out) {
  ChildResult r;
  int fds[2];
  if (::pipe2(fds, O_CLOEXEC) != 0) {
    r.error = std::string("pipe: ") + std::strerror(errno);
    return r;
  }
  const int err_fd = ::open(stderr_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (err_fd < 0) {
    r.error = "cannot write " + stderr_path + ": " + std::strerror(errno);
    ::close(fds[0]);
    ::close(fds[1]);
    return r;
  }
  posix_spawn_file_actions_t fa;
  posix_spawn_file_actions_init(&fa);
  posix_spawn_file_actions_adddup2(&fa, fds[1], STDOUT_FILENO);
  posix_spawn_file_actions_adddup2(&fa, err_fd, STDERR_FILENO);
  posix_spawnattr_t attr;
  posix_spawnattr_init(&attr);
  sigset_t none, defaults;
  sigemptyset(&none);
  sigemptyset(&defaults);
  sigaddset(&defaults, SIGINT);
  sigaddset(&defaults, SIGTERM);
  sigaddset(&defaults, SIGPIPE);
  posix_spawnattr_setsigmask(&attr, &none);
  posix_spawnattr_setsigdefault(&attr, &defaults);
  posix_spawnattr_setpgroup(&attr, 0);
  posix_spawnattr_setflags(&attr, POSIX_SPAWN_SETPGROUP | POSIX_SPAWN_SETSIGMASK | POSIX_SPAWN_SETSIGDEF);
  std::vector<char*> cargv;
  std::vector<std::string> copy = argv;
  for (auto& a : copy) cargv.push_back(a.data());
  cargv.push_back(nullptr);
  std::fflush(stdout);
  std::fflush(stderr);
  const auto t0 = std::chrono::steady_clock::now();
  pid_t pid = -1;
  // /proc/self/exe, resolved in the child: this very binary, even if a rebuild has replaced the file.
  const int rc = ::posix_spawn(&pid, "/proc/self/exe", &fa, &attr, cargv.data(), environ);
  posix_spawn_file_actions_destroy(&fa);
  posix_spawnattr_destroy(&attr);
  ::close(fds[1]);
  ::close(err_fd);
  if (rc != 0) {
    r.error = "cannot start " + argv[0] + ": " + std::strerror(rc);
    ::close(fds[0]);
    return r;
  }
  r.started = true;
  std::ofstream log(stdout_path, std::ios::binary);
  const auto elapsed = [&] {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  };
  double term_sent_at = -1;
  bool eof = false, reaped = false;
  int status = 0;
  double reaped_at = 0;
  char buf[65536];
  while (!eof) {
    if (!reaped && ::waitpid(pid, &status, WNOHANG) == pid) {
      reaped = true;
      reaped_at = elapsed();
    }
    // The child has exited but something it started still holds the pipe: give it 5 s.
    if (reaped && elapsed() - reaped_at > 5) break;
    if (term_sent_at < 0 && (g_interrupted || elapsed() > timeout_s)) {
      r.timed_out = !g_interrupted;
      r.interrupted = g_interrupted != 0;
      kill_group(pid, SIGTERM);
      term_sent_at = elapsed();
    }
    if (term_sent_at >= 0 && elapsed() - term_sent_at > 10) kill_group(pid, SIGKILL);
    pollfd p{fds[0], POLLIN, 0};
    const int n = ::poll(&p, 1, 200);
    if (n < 0 && errno != EINTR) break;
    if (n <= 0) continue;
    const ssize_t got = ::read(fds[0], buf, sizeof(buf));
    if (got < 0 && errno == EINTR) continue;
    if (got <= 0) {
      eof = true;
      break;
    }
    out->append(buf, static_cast<size_t>(got));
    log.write(buf, got);
  }
  ::close(fds[0]);
  if (!reaped) {
    while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
      if (g_interrupted && term_sent_at < 0) {
        kill_group(pid, SIGTERM);
        term_sent_at = elapsed();
      }
    }
  }
  // Something it started still holds the pipe (so its group still exists): end it.
  if (!eof) kill_group(pid, SIGKILL);
  r.wall_s = elapsed();
  if (WIFEXITED(status)) r.exit_code = WEXITSTATUS(status);
  if (WIFSIGNALED(status)) r.signal = WTERMSIG(status);
  return r;
}

RunResult execute(const std::string& exe, const RunSpec& spec, const Options& o, size_t index, size_t count) {
  RunResult r;
  r.id = spec.id;
  std::vector<std::string> argv = {exe, spec.id};
  argv.insert(argv.end(), spec.args.begin(), spec.args.end());
  r.command = command_line(argv);
  if (o.skip.count(spec.id)) {
    r.why_not = "skipped (--skip " + spec.id + ")";
    return r;
  }
  if (!spec.not_built.empty()) {
    r.why_not = spec.not_built;
    return r;
  }
  for (const std::string& need : spec.needs) {
    if (!fs::exists(need)) {
      r.why_not = "dataset absent: " + need;
      return r;
    }
  }
  if (g_interrupted) {
    r.why_not = "not run (interrupted)";
    return r;
  }
  std::fprintf(stderr, "paper: [%zu/%zu] %s\n", index, count, r.command.c_str());
  const std::string base = o.out_dir + "/runs/" + spec.id;
  std::string out;
  const ChildResult c = run_child(argv, base + ".stdout", base + ".stderr", o.run_timeout_s, &out);
  r.ran = c.started;
  r.wall_s = c.wall_s;
  r.exit_code = c.exit_code;
  r.keys = paper::parse_key_values(out);
  char why[160];
  if (!c.started) {
    r.why_not = c.error;
  } else if (c.interrupted) {
    r.why_not = "interrupted";
  } else if (c.timed_out) {
    std::snprintf(why, sizeof(why), "timed out after %.0f s", o.run_timeout_s);
    r.why_not = why;
  } else if (c.signal != 0) {
    std::snprintf(why, sizeof(why), "killed by signal %d", c.signal);
    r.why_not = why;
  } else if (c.exit_code != 0) {
    std::snprintf(why, sizeof(why), "exit code %d", c.exit_code);
    r.why_not = why;
  } else {
    r.ok = true;
  }
  std::fprintf(stderr, "paper: [%zu/%zu] %s: %s in %.1f s, %zu key lines (%s.stdout, .stderr)\n", index,
               count, spec.id.c_str(), r.ok ? "done" : r.why_not.c_str(), r.wall_s, r.keys.lines.size(),
               base.c_str());
  return r;
}

// ---- the tables ----

const RunResult& run_of(const std::map<std::string, RunResult>& runs, const std::string& id) {
  static const RunResult kNotPlanned = [] {
    RunResult r;
    r.id = "?";
    r.why_not = "not planned";
    return r;
  }();
  const auto it = runs.find(id);
  return it == runs.end() ? kNotPlanned : it->second;
}

Cell with_suffix(Cell c, const std::string& suffix) {
  if (c.available) c.text += suffix;
  return c;
}

std::string sim_label(const std::string& seq, double duration_s) {
  char buf[96];
  std::snprintf(buf, sizeof(buf), "%s (sim, first %.0f s)", seq.c_str(), duration_s);
  return buf;
}

std::string seq_label(const std::string& seq, double duration_s) {
  return seq == "teddy" ? std::string("teddy (TUM fr3, real, 193 frames)") : sim_label(seq, duration_s);
}

// A run that does not cover a sequence says why, in place of its key's absence.
RunResult without_sequence(const RunResult& run, const std::string& why) {
  RunResult r = run;
  r.ok = false;
  r.why_not = why;
  return r;
}

Table table_one(const std::map<std::string, RunResult>& runs, const Plan& plan) {
  Table t;
  t.id = "I";
  t.title = "Time cost per frame [ms], mean ± sd; and ATE [m] of the same runs";
  t.row_header = "";
  t.columns = {"ORB-SLAM3 [30]", "VINS-RGBD [34]",      "LSD-SLAM [25]",     "Chi et al. [3]",
               "Ours",           "RgbdOdometry (peer)", "paper ours / ours", "peer / ours"};
  const Cell paper_ours = paper::paper_cell("162.4 ± 19.1", 162.4, "paper Table I", "paper_t1_paper_ms_ours");
  t.rows.push_back({"paper (Jetson AGX, outdoor)",
                    {paper::paper_cell("158.2 ± 45.7", 158.2, "paper Table I", "paper_t1_paper_ms_orbslam3"),
                     paper::paper_cell("56.0 ± 28.5", 56.0, "paper Table I", "paper_t1_paper_ms_vins_rgbd"),
                     paper::paper_cell("72.9 ± 32.8", 72.9, "paper Table I", "paper_t1_paper_ms_lsd_slam"),
                     paper::paper_cell("358.2 ± 94.3", 358.2, "paper Table I", "paper_t1_paper_ms_chi"),
                     paper_ours, paper::dash_cell(), paper::dash_cell(), paper::dash_cell()}});
  const RunResult& frame = run_of(runs, "frame");
  const std::vector<std::string> seqs = {"teddy", "lab", "outdoor"};
  const auto covered = [&](const std::string& s) {
    if (std::find(plan.frame_sequences.begin(), plan.frame_sequences.end(), s) != plan.frame_sequences.end())
      return frame;
    return without_sequence(frame,
                            s == "teddy" ? "dataset absent: " + kTeddy : "not in this run's --sequences");
  };
  const std::vector<Cell> none(4, paper::dash_cell());
  for (const std::string& s : seqs) {
    const RunResult r = covered(s);
    Row row{"this run: " + seq_label(s, plan.sim_duration_s) + ", ms", none};
    const Cell ours =
        paper::run_mean_sd_cell(r, "frame_ms_mean_" + s, "frame_ms_sd_" + s, "paper_t1_ours_ms_" + s);
    row.cells.push_back(ours);
    row.cells.push_back(paper::run_mean_sd_cell(r, "rgbd_odometry_ms_mean_" + s, "rgbd_odometry_ms_sd_" + s,
                                                "paper_t1_peer_ms_" + s));
    row.cells.push_back(paper::ratio_cell(paper_ours, ours, "paper_t1_paper_over_ours_" + s));
    row.cells.push_back(with_suffix(
        paper::run_cell(r, "speedup_vs_rgbd_odometry_" + s, "paper_t1_peer_over_ours_" + s), "×"));
    t.rows.push_back(row);
  }
  for (const std::string& s : seqs) {
    const RunResult r = covered(s);
    Row row{"this run: " + seq_label(s, plan.sim_duration_s) + ", ATE m", none};
    const Cell ours = paper::run_cell(r, "ate_m_" + s, "paper_t1_ours_ate_m_" + s);
    const Cell peer = paper::run_cell(r, "ate_m_" + s + "_rgbd_odometry", "paper_t1_peer_ate_m_" + s);
    row.cells.push_back(ours);
    row.cells.push_back(peer);
    row.cells.push_back(paper::dash_cell());
    row.cells.push_back(paper::ratio_cell(peer, ours, "paper_t1_peer_over_ours_ate_" + s));
    t.rows.push_back(row);
  }
  t.notes = {
      "paper: Jetson AGX, ZED 2i, the outdoor scene; ORB-SLAM3, VINS-RGBD, LSD-SLAM and Chi et al. are the "
      "paper's figures, not run here.",
      "this run: this host; ours = the camera task per frame on one thread (IMU propagation, ORB, matching, "
      "pose, keyframe; the sliding-window BA runs in the mapping task, not in it); peer = OpenCV-contrib "
      "cv::rgbd::RgbdOdometry frame to frame on the same frames in the same run (no peer of the paper's "
      "list runs here).",
      "paper ours / ours compares different machines (AGX vs this host); peer / ours is the same machine "
      "and run. ATE: SE(3)-aligned RMSE (hwr-eval ate), the paper's Table I has no ATE."};
  return t;
}

Table table_two(const std::map<std::string, RunResult>& runs, const Plan& plan) {
  Table t;
  t.id = "II";
  t.title = "Map transmission: last point on the ground after the stop [s], direct vs segmented (streamed)";
  t.row_header = "size [10^6 points]";
  struct Paper {
    const char* size;
    const char* direct;
    const char* segmented;
  };
  const Paper paper[] = {{"0.1", "1.25", "1.25"},
                         {"0.9", "3.95", "2.32"},
                         {"1.7", "9.67", "2.74"},
                         {"2.5", "26.79", "2.65"},
                         {"3.8", "48.95", "2.38"}};
  Row pd{"paper: direct", {}}, ps{"paper: segmentation", {}}, od{"this run: direct (1 Gbit/s)", {}},
      os{"this run: ours, streamed (1 Gbit/s)", {}}, rd{"paper direct / this run direct", {}},
      rs{"paper segmentation / this run ours", {}}, lb{"this run: bytes on the link / raw xyz+rgb", {}};
  const RunResult& transfer = run_of(runs, "transfer");
  for (const Paper& p : paper) {
    t.columns.push_back(p.size);
    const std::string tag = std::string("1000mbit_") + p.size + "m";
    const std::string k = std::string(p.size) + "m";
    const Cell cpd =
        paper::paper_cell(p.direct, std::atof(p.direct), "paper Table II", "paper_t2_paper_direct_s_" + k);
    const Cell cps = paper::paper_cell(p.segmented, std::atof(p.segmented), "paper Table II",
                                       "paper_t2_paper_segmented_s_" + k);
    const bool run_here = std::find(plan.sizes.begin(), plan.sizes.end(), p.size) != plan.sizes.end();
    const RunResult r = run_here ? transfer : without_sequence(transfer, "not in this run's --sizes");
    const Cell cod = paper::run_cell(r, "latency_s_direct_" + tag, "paper_t2_direct_s_" + k);
    const Cell cos = paper::run_cell(r, "latency_s_ours_" + tag, "paper_t2_ours_s_" + k);
    pd.cells.push_back(cpd);
    ps.cells.push_back(cps);
    od.cells.push_back(cod);
    os.cells.push_back(cos);
    rd.cells.push_back(paper::ratio_cell(cpd, cod, "paper_t2_paper_over_direct_" + k));
    rs.cells.push_back(paper::ratio_cell(cps, cos, "paper_t2_paper_over_ours_" + k));
    lb.cells.push_back(paper::run_cell(r, "link_bytes_ratio_" + tag, "paper_t2_link_bytes_ratio_" + k));
  }
  t.rows = {pd, ps, od, os, rd, rs, lb};
  std::string compression = "?";
  if (transfer.ok)
    if (const std::string* v = transfer.keys.find("time_compression")) compression = *v;
  t.notes = {
      "paper: outdoor scene, wired network, local maps cut at 5×10^5 points. this run: the sim lab walk's "
      "point stream (the local mapper's batches), LCM UDP multicast between a MapStreamer and a "
      "GroundStation "
      "in a private network namespace, lo shaped to 1 Gbit/s (tc tbf), MTU 1500; decoded and stored on the "
      "ground.",
      "direct = the whole map encoded and sent at the stop; ours = the batches streamed while the map fills "
      "(the mapping timeline replayed " +
          compression +
          "× faster than simulated time, transfer: time_compression); no peer (the paper's direct "
          "transmission is the baseline)."};
  return t;
}

Table table_three(const std::map<std::string, RunResult>& runs, const Plan& plan, const Options& o) {
  Table t;
  t.id = "III";
  t.title = "Map segmentation's influence on ATE [m] and AE [mm]";
  t.row_header = "";
  t.columns = {"ATE lab [m]", "ATE outdoor [m]", "AE lab [mm]", "AE outdoor [mm]"};
  const std::string where = "paper Table III";
  t.rows.push_back({"paper: without segmentation",
                    {paper::paper_cell("0.138", 0.138, where, "paper_t3_paper_ate_m_lab_without"),
                     paper::paper_cell("0.341", 0.341, where, "paper_t3_paper_ate_m_outdoor_without"),
                     paper::paper_cell("80", 80, where, "paper_t3_paper_ae_mm_lab_without"),
                     paper::paper_cell("208", 208, where, "paper_t3_paper_ae_mm_outdoor_without")}});
  t.rows.push_back({"paper: with segmentation",
                    {paper::paper_cell("0.142", 0.142, where, "paper_t3_paper_ate_m_lab_with"),
                     paper::paper_cell("0.349", 0.349, where, "paper_t3_paper_ate_m_outdoor_with"),
                     paper::paper_cell("83", 83, where, "paper_t3_paper_ae_mm_lab_with"),
                     paper::paper_cell("214", 214, where, "paper_t3_paper_ae_mm_outdoor_with")}});
  t.rows.push_back({"paper: difference (%)",
                    {paper::paper_cell("-2.89", -2.89, where, "paper_t3_paper_ate_diff_pct_lab"),
                     paper::paper_cell("-2.34", -2.34, where, "paper_t3_paper_ate_diff_pct_outdoor"),
                     paper::paper_cell("-3.75", -3.75, where, "paper_t3_paper_ae_diff_pct_lab"),
                     paper::paper_cell("-2.88", -2.88, where, "paper_t3_paper_ae_diff_pct_outdoor")}});
  const RunResult& seg = run_of(runs, "segmentation");
  const auto covered = [&](const std::string& s) {
    return (s == "outdoor" && o.quick) ? without_sequence(seg, "not in this run's --sequences") : seg;
  };
  Row without{"this run: without segmentation", {}}, with{"this run: with segmentation", {}},
      diff{"this run: difference (%), the paper's sign", {}}, r0{"paper / this run, without", {}},
      r1{"paper / this run, with", {}}, seen{"this run: plates seen (AE)", {}};
  for (const char* what : {"ate_m", "ae_mm"}) {
    for (const char* scene : {"lab", "outdoor"}) {
      const std::string s = scene;
      const RunResult r = covered(s);
      const std::string k = std::string(what) + "_" + s;
      const bool ate = std::string(what) == "ate_m";
      const std::string key0 = (ate ? "seg_ate_m_" : "seg_ae_mm_") + s + "_without";
      const std::string key1 = (ate ? "seg_ate_m_" : "seg_ae_mm_") + s + "_with";
      const Cell c0 = paper::run_cell(r, key0, "paper_t3_" + k + "_without");
      const Cell c1 = paper::run_cell(r, key1, "paper_t3_" + k + "_with");
      without.cells.push_back(c0);
      with.cells.push_back(c1);
      // The paper's difference is (without - with) / without, negative when segmentation is worse;
      // the bench's seg_ate_diff_pct_* has the other sign.
      const std::string dkey = std::string("paper_t3_") + (ate ? "ate" : "ae") + "_diff_pct_" + s;
      if (ate) {
        const Cell d = paper::run_cell(r, "seg_ate_diff_pct_" + s, dkey);
        if (d.available) {
          char text[32];
          std::snprintf(text, sizeof(text), "%.2f", -d.value);
          diff.cells.push_back(paper::derived_cell(-d.value, text, "-(seg_ate_diff_pct_" + s + ")", dkey));
        } else {
          diff.cells.push_back(d);
        }
      } else if (c0.available && c1.available) {
        const double v = 100.0 * (c0.value - c1.value) / c0.value;
        char text[32];
        std::snprintf(text, sizeof(text), "%.2f", v);
        diff.cells.push_back(
            paper::derived_cell(v, text, "100·(" + key0 + " − " + key1 + ") / " + key0, dkey));
      } else {
        diff.cells.push_back(paper::na_cell("needs " + key0 + " and " + key1, dkey));
      }
      const size_t col = without.cells.size() - 1;
      r0.cells.push_back(
          paper::ratio_cell(t.rows[0].cells[col], c0, "paper_t3_paper_over_" + k + "_without"));
      r1.cells.push_back(paper::ratio_cell(t.rows[1].cells[col], c1, "paper_t3_paper_over_" + k + "_with"));
      seen.cells.push_back(ate ? paper::dash_cell()
                               : paper::run_cell(r, "plates_seen_" + s, "paper_t3_plates_seen_" + s));
    }
  }
  t.rows.insert(t.rows.end(), {without, with, diff, r0, r1, seen});
  char note[400];
  std::snprintf(
      note, sizeof(note),
      "this run: the first %.0f s of each sim walk (segmentation --duration), the simulator's exact "
      "ground truth; ATE on the trajectory before the end-of-run full BA, with segmentation = each "
      "segment carried by the chain of its ORB + NDT junctions.",
      plan.seg_duration_s);
  t.notes = {
      "paper: lab ground truth from LiDAR SLAM, outdoor from RTK; AE against fixed-size steel plates.", note,
      "AE on the welding regions' fine clouds (the simulator's joints as the detections); difference in the "
      "paper's sign, (without − with) / without. No peer: none of the paper's comparisons runs here."};
  return t;
}

Table table_four(const std::map<std::string, RunResult>& runs, const Plan& plan, const Options& o) {
  Table t;
  t.id = "IV";
  t.title = "Relocalization time [s], mean ± sd";
  t.row_header = "";
  t.columns = {"only GNSS", "only IMU", "GNSS and IMU", "neither (not in the paper)"};
  const std::string where = "paper Table IV";
  const Cell po[] = {paper::paper_cell("12.64 ± 2.83", 12.64, where, "paper_t4_paper_s_outdoor_gnss"),
                     paper::paper_cell("16.24 ± 2.68", 16.24, where, "paper_t4_paper_s_outdoor_imu"),
                     paper::paper_cell("1.57 ± 0.67", 1.57, where, "paper_t4_paper_s_outdoor_both")};
  const Cell pl = paper::paper_cell("15.37 ± 2.39", 15.37, where, "paper_t4_paper_s_lab_imu");
  t.rows.push_back({"paper: outdoor", {po[0], po[1], po[2], paper::dash_cell()}});
  t.rows.push_back(
      {"paper: laboratory", {paper::dash_cell("\\"), pl, paper::dash_cell("\\"), paper::dash_cell()}});
  const RunResult& reloc = run_of(runs, "reloc");
  const char* sets[] = {"gnss", "imu", "both", "neither"};
  for (const char* scene_name : {"outdoor", "lab"}) {
    const std::string scene = scene_name;
    const RunResult r =
        (scene == "outdoor" && o.quick) ? without_sequence(reloc, "not in this run's --scenes") : reloc;
    const std::string name = scene == "lab" ? "laboratory" : scene;
    Row mean{"this run: " + name + ", s", {}}, success{"this run: " + name + ", success %", {}},
        median{"this run: " + name + ", median of all starts, s", {}}, ratio{"paper / this run, " + name, {}};
    for (int k = 0; k < 4; ++k) {
      const std::string set = sets[k];
      const std::string prefix = "reloc_" + scene + "_" + set;
      if (scene == "lab" && (set == "gnss" || set == "both")) {
        for (Row* row : {&mean, &success, &median, &ratio})
          row->cells.push_back(paper::dash_cell("\\ (no GNSS indoors)"));
        continue;
      }
      const Cell m = paper::run_mean_sd_cell(r, prefix + "_mean_s_successful", prefix + "_sd_s_successful",
                                             "paper_t4_s_" + scene + "_" + set);
      mean.cells.push_back(m);
      success.cells.push_back(
          paper::run_cell(r, prefix + "_success_pct", "paper_t4_success_pct_" + scene + "_" + set));
      median.cells.push_back(
          paper::run_cell(r, prefix + "_median_s", "paper_t4_median_s_" + scene + "_" + set));
      const Cell* p = scene == "outdoor" ? (k < 3 ? &po[k] : nullptr) : (set == "imu" ? &pl : nullptr);
      ratio.cells.push_back(p ? paper::ratio_cell(*p, m, "paper_t4_paper_over_ours_" + scene + "_" + set)
                              : paper::dash_cell());
    }
    t.rows.insert(t.rows.end(), {mean, success, median, ratio});
  }
  std::string false_text = "?";
  if (reloc.ok) {
    const std::string* f = reloc.keys.find("reloc_false");
    const std::string* i = reloc.keys.find("reloc_inaccurate");
    false_text = std::string("reloc_false=") + (f ? *f : "?") + ", reloc_inaccurate=" + (i ? *i : "?");
  }
  const std::string note =
      "this run: the simulator's revisits (another day, a plate moved, started elsewhere) against the prior "
      "map hwr-robot built on the first visit (reloc's cache), " +
      std::to_string(plan.reloc_starts) +
      " starts per scene; time = the sum of the attempts' relocalize() wall times up to success (compute "
      "only, the walking between attempts not counted), mean ± sd over the successful starts; the median "
      "counts a start never localized as infinite. False / inaccurate poses: " +
      false_text + ".";
  t.notes = {
      "paper: Jetson AGX, the real robot; only IMU = the magnetometer's yaw prior; \\ = no GNSS indoors.",
      note, "No peer: the paper compares sensor sets, not methods."};
  return t;
}

Table table_real(const std::map<std::string, RunResult>& runs) {
  Table t;
  t.id = "R";
  t.title = "Real datasets present, and the benches' sim problems (no paper figure): ours beside the peer";
  t.row_header = "";
  t.columns = {"paper", "ours (this run)", "peer (this run)", "peer / ours"};
  const RunResult& ba = run_of(runs, "ba");
  const RunResult& ndt = run_of(runs, "ndt");
  const RunResult& imu = run_of(runs, "imu");
  const auto row = [&](const std::string& label, const RunResult& r, const std::string& ours_key,
                       const std::string& peer_key, const std::string& ratio_key, const std::string& id) {
    const Cell ours = paper::run_cell(r, ours_key, "paper_r_ours_" + id);
    const Cell peer =
        peer_key.empty() ? paper::dash_cell() : paper::run_cell(r, peer_key, "paper_r_peer_" + id);
    Cell ratio = paper::dash_cell();
    if (!ratio_key.empty()) {
      ratio = with_suffix(paper::run_cell(r, ratio_key, "paper_r_peer_over_ours_" + id), "×");
    } else if (!peer_key.empty()) {
      ratio = paper::ratio_cell(peer, ours, "paper_r_peer_over_ours_" + id);
    }
    t.rows.push_back({label, {paper::dash_cell(), ours, peer, ratio}});
  };
  const std::pair<const char*, const char*> problems[] = {
      {"ladybug49", "BA, BAL Ladybug 49-7776: ms to the common cost (peer Ceres)"},
      {"ladybug49_1800", "BA, Ladybug 1800-point reduction: ms (peer Ceres)"},
      {"teddy_full", "BA, TUM teddy run's full BA: ms (peer Ceres)"},
      {"rgbd_window", "BA, synthetic RGB-D window: ms (peer Ceres)"},
      {"lab_full_30s", "BA, sim lab 30 s run's full BA: ms (peer Ceres)"}};
  for (const auto& [problem, label] : problems) {
    const std::string p = problem;
    row(label, ba, "ba_ms_" + p, "ceres_ms_" + p, "ba_speedup_vs_ceres_" + p, "ba_ms_" + p);
  }
  for (const char* dataset : {"lidar", "car", "room", "room-synth", "sim-lab"}) {
    const std::string d = dataset;
    std::string id = d;
    std::replace(id.begin(), id.end(), '-', '_');
    row("NDT, " + d + " pair: ms (peer PCL 1.13, coarse to fine)", ndt, "ndt_ms_" + d, "pcl_ms_" + d,
        "ndt_speedup_vs_pcl_" + d, "ndt_ms_" + id);
  }
  row("NDT, translation error where both converge, cm", ndt, "ndt_err_cm", "pcl_err_cm", "", "ndt_err_cm");
  row("NDT, success over the offset grid, %", ndt, "ndt_success_pct", "pcl_success_pct", "",
      "ndt_success_pct");
  row("IMU, EuRoC V1_01 static init: gravity tilt error, deg", imu, "imu_static_tilt_err_deg", "", "",
      "imu_tilt_deg");
  row("IMU, EuRoC V1_01 static init: gyro bias error, rad/s", imu, "imu_static_gyro_bias_err_radps", "", "",
      "imu_gyro_bias_radps");
  row("IMU only from the static init, V1_01: position error at 10 s, m", imu, "imu_only_pos_err_m_v1_01_10s",
      "", "", "imu_pos_m_v1_01_10s");
  row("IMU only from the GT state, V1_02: position error at 10 s, m", imu, "imu_only_pos_err_m_v1_02_10s", "",
      "", "imu_pos_m_v1_02_10s");
  t.notes = {
      "BA: time for both solvers to reach the same final cost (within 0.1 %), Ceres SPARSE_SCHUR on one "
      "thread "
      "(ba: ba_speedup_vs_ceres_*).",
      "NDT: ours on one thread vs PCL 1.13 NormalDistributionsTransform coarse to fine (ndt: "
      "ndt_speedup_vs_pcl_*); sim-lab is the simulator's pair, the others real scans. IMU: no peer."};
  return t;
}

// ---- trajectory plots ----

struct PlotResult {
  std::string sequence, png, note;  // note: why not, or the ATE check
  bool ok = false;
  std::vector<Cell> key_cells;
};

PlotResult plot_sequence(const std::string& seq, const std::string& traj_dir, const std::string& out_dir,
                         const RunResult& frame, double duration_s) {
  PlotResult r;
  r.sequence = seq;
  r.png = out_dir + "/trajectory_" + seq + ".png";
  auto gt = core::read_tum_trajectory(traj_dir + "/" + seq + "_groundtruth.tum");
  auto ours = core::read_tum_trajectory(traj_dir + "/" + seq + "_ours.tum");
  if (!gt.ok() || !ours.ok()) {
    r.note = "no plot: " + (!gt.ok() ? gt.status().message() : ours.status().message());
    return r;
  }
  auto ours_aligned = paper::align_to_groundtruth(gt.value(), ours.value());
  if (!ours_aligned.ok()) {
    r.note = "no plot: " + ours_aligned.status().message();
    return r;
  }
  char label[160];
  std::vector<paper::PlotTrack> tracks;
  paper::PlotTrack g;
  g.label = "ground truth";
  g.poses = paper::groundtruth_span(gt.value(), ours.value());
  g.bgr[0] = g.bgr[1] = g.bgr[2] = 40;
  g.thick = true;
  tracks.push_back(g);
  paper::PlotTrack o;
  std::snprintf(label, sizeof(label), "hwr (ours), ATE %.4f m", ours_aligned->ate_rmse_m);
  o.label = label;
  o.poses = ours_aligned->poses;
  o.bgr[0] = 200, o.bgr[1] = 90, o.bgr[2] = 20;  // blue
  tracks.push_back(o);
  // The ATE of the written trajectories against the bench's key (rounding of the file and the key apart).
  const std::string* key = frame.keys.find("ate_m_" + seq);
  char check[200];
  std::snprintf(check, sizeof(check), "ATE from the files %.5f m, frame: ate_m_%s=%s",
                ours_aligned->ate_rmse_m, seq.c_str(), key ? key->c_str() : "(absent)");
  r.note = check;
  // As the frame bench prints its ATE keys (%.5f), so the two compare as text.
  const auto five = [](double v) {
    char b[32];
    std::snprintf(b, sizeof(b), "%.5f", v);
    return std::string(b);
  };
  r.key_cells.push_back(paper::derived_cell(ours_aligned->ate_rmse_m, five(ours_aligned->ate_rmse_m), "",
                                            "paper_plot_ate_m_" + seq));
  auto peer = core::read_tum_trajectory(traj_dir + "/" + seq + "_rgbd_odometry.tum");
  if (peer.ok()) {
    auto peer_aligned = paper::align_to_groundtruth(gt.value(), peer.value());
    if (peer_aligned.ok()) {
      paper::PlotTrack p;
      std::snprintf(label, sizeof(label), "RgbdOdometry (peer), ATE %.4f m", peer_aligned->ate_rmse_m);
      p.label = label;
      p.poses = peer_aligned->poses;
      p.bgr[0] = 30, p.bgr[1] = 120, p.bgr[2] = 230;  // orange
      tracks.push_back(p);
      r.key_cells.push_back(paper::derived_cell(peer_aligned->ate_rmse_m, five(peer_aligned->ate_rmse_m), "",
                                                "paper_plot_peer_ate_m_" + seq));
    }
  }
  const std::string title =
      seq_label(seq, duration_s) + ": top view (x-y), estimates SE(3)-aligned to the ground truth";
  const core::Status st = paper::write_trajectory_png(r.png, title, tracks);
  if (!st.ok()) {
    r.note = "no plot: " + st.message();
    return r;
  }
  r.ok = true;
  return r;
}

// ---- the report ----

std::string now_utc() {
  const std::time_t t = std::time(nullptr);
  char buf[64];
  std::strftime(buf, sizeof(buf), "%Y-%m-%d %H:%M:%S UTC", std::gmtime(&t));
  return buf;
}

std::string markdown_report(const std::vector<RunResult>& runs, const std::vector<Table>& tables,
                            const std::vector<PlotResult>& plots, const Options& o, double wall_s,
                            const std::string& started, const std::string& command) {
  std::ostringstream md;
  md << "# hwr-bench paper: the paper's Tables I–IV beside this run\n\n";
  md << "`" << command << "`\n\n";
  char buf[256];
  std::snprintf(buf, sizeof(buf),
                "Started %s; %.1f s wall in all%s. Every figure below comes from a sub-run's "
                "`key=value` line (cell: value, then `run: key`); rerun a sub-run with its command line to "
                "compare.\n\n",
                started.c_str(), wall_s, o.quick ? " (--quick)" : "");
  md << buf;
  md << "## Sub-runs\n\n| run | command | result | wall [s] | key lines |\n|---|---|---|---:|---:|\n";
  for (const RunResult& r : runs) {
    std::snprintf(buf, sizeof(buf), "%.1f", r.wall_s);
    md << "| " << r.id << " | `" << r.command << "` | " << (r.ok ? std::string("ok") : r.why_not) << " | "
       << (r.ran ? buf : "-") << " | " << r.keys.lines.size() << " |\n";
  }
  md << "\nEach run's stdout and stderr: `runs/<run>.stdout`, `runs/<run>.stderr` (in this folder).\n\n";
  md << "## Tables\n\n";
  for (const Table& t : tables) md << paper::render_markdown(t);
  md << "## Trajectories (top view, estimates aligned to the ground truth as their ATE)\n\n";
  for (const PlotResult& p : plots) {
    if (p.ok) {
      md << "### " << p.sequence << "\n\n![" << p.sequence << "](" << fs::path(p.png).filename().string()
         << ")\n\n"
         << p.note << "\n\n";
    } else {
      md << "### " << p.sequence << "\n\n" << p.note << "\n\n";
    }
  }
  return md.str();
}

int usage(const char* why) {
  std::fprintf(stderr,
               "hwr-bench paper: %s\nusage: hwr-bench paper [--out DIR] [--quick] [--skip "
               "frame,segmentation,transfer,reloc,imu,ba,ndt] [--duration S] [--run-timeout S] [--dry-run]\n",
               why);
  return 2;
}

int run_paper(int argc, char** argv) {
  Options o;
  o.out_dir = fs::is_directory("build") ? "build/paper-report" : "paper-report";
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    const bool v = i + 1 < argc;
    if (a == "--out" && v) {
      o.out_dir = argv[++i];
    } else if (a == "--quick") {
      o.quick = true;
    } else if (a == "--skip" && v) {
      std::stringstream ss(argv[++i]);
      for (std::string s; std::getline(ss, s, ',');) {
        if (s.empty()) continue;
        if (std::find(std::begin(kAllIds), std::end(kAllIds), s) == std::end(kAllIds))
          return usage(("--skip: unknown run '" + s + "'").c_str());
        o.skip.insert(s);
      }
    } else if (a == "--duration" && v) {
      o.duration_s = std::atof(argv[++i]);
      if (!(o.duration_s > 0)) return usage("--duration takes seconds > 0");
    } else if (a == "--run-timeout" && v) {
      o.run_timeout_s = std::atof(argv[++i]);
      if (!(o.run_timeout_s > 0)) return usage("--run-timeout takes seconds > 0");
    } else if (a == "--dry-run") {
      o.dry_run = true;
    } else if (a == "--help" || a == "-h") {
      usage("the paper's Tables I-IV from the other benches, beside the paper's and the peers' figures");
      return 0;
    } else {
      return usage(("unknown or incomplete option '" + a + "'").c_str());
    }
  }
  const std::string exe = self_exe();
  if (exe.empty()) {
    std::fprintf(stderr, "hwr-bench paper: cannot read /proc/self/exe\n");
    return 1;
  }
  std::error_code ec;
  fs::create_directories(o.out_dir, ec);
  if (!ec) o.out_dir = fs::absolute(o.out_dir, ec).lexically_normal().string();
  const std::string traj_dir = o.out_dir + "/trajectories";
  if (!ec) fs::create_directories(o.out_dir + "/runs", ec);
  if (!ec) fs::create_directories(traj_dir, ec);
  if (ec) {
    std::fprintf(stderr, "hwr-bench paper: cannot create %s: %s\n", o.out_dir.c_str(), ec.message().c_str());
    return 1;
  }
  const Plan plan = make_plan(o, traj_dir);
  if (o.dry_run) {
    for (const RunSpec& s : plan.runs) {
      std::vector<std::string> sub = {exe, s.id};
      sub.insert(sub.end(), s.args.begin(), s.args.end());
      std::printf("%s%s\n", command_line(sub).c_str(), o.skip.count(s.id) ? "   # skipped" : "");
    }
    return 0;
  }
  // Old trajectories would be plotted as this run's.
  for (const auto& entry : fs::directory_iterator(traj_dir, ec))
    if (entry.path().extension() == ".tum") fs::remove(entry.path(), ec);

  struct sigaction sa {};
  sa.sa_handler = on_interrupt;
  sigemptyset(&sa.sa_mask);
  ::sigaction(SIGINT, &sa, nullptr);
  ::sigaction(SIGTERM, &sa, nullptr);

  const std::string started = now_utc();
  std::vector<std::string> own = {exe};
  own.insert(own.end(), argv, argv + argc);
  const std::string paper_command = command_line(own);
  const auto t0 = std::chrono::steady_clock::now();
  std::vector<RunResult> results;
  std::map<std::string, RunResult> by_id;
  for (size_t k = 0; k < plan.runs.size(); ++k) {
    results.push_back(execute(exe, plan.runs[k], o, k + 1, plan.runs.size()));
    by_id[results.back().id] = results.back();
  }

  std::vector<Table> tables = {table_one(by_id, plan), table_two(by_id, plan), table_three(by_id, plan, o),
                               table_four(by_id, plan, o), table_real(by_id)};
  std::vector<PlotResult> plots;
  const RunResult& frame = run_of(by_id, "frame");
  for (const std::string& seq : plan.frame_sequences) {
    if (!frame.ok) {
      PlotResult p;
      p.sequence = seq;
      p.note = "no plot: frame " + frame.why_not;
      plots.push_back(p);
      continue;
    }
    plots.push_back(plot_sequence(seq, traj_dir, o.out_dir, frame, plan.sim_duration_s));
  }
  const double wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();

  // stdout: the sub-runs, the tables, the plots, then the key lines.
  std::printf("hwr-bench paper: %zu sub-runs, %.1f s wall; report in %s\n", results.size(), wall_s,
              o.out_dir.c_str());
  for (const RunResult& r : results)
    std::printf("  %-12s %-30s %7.1f s  %s\n", r.id.c_str(), r.ok ? "ok" : r.why_not.c_str(), r.wall_s,
                r.command.c_str());
  for (const Table& t : tables) std::printf("\n%s", paper::render_text(t).c_str());
  std::printf("\n");
  for (const PlotResult& p : plots)
    std::printf("trajectory %s: %s (%s)\n", p.sequence.c_str(), p.ok ? p.png.c_str() : "-", p.note.c_str());
  std::printf("\n");
  for (const Table& t : tables) std::printf("%s", paper::render_key_lines(t).c_str());
  for (const PlotResult& p : plots)
    for (const Cell& c : p.key_cells) std::printf("%s=%s\n", c.key.c_str(), c.value_text.c_str());
  for (const RunResult& r : results) {
    std::printf("paper_run_%s_ok=%d\n", r.id.c_str(), r.ok ? 1 : 0);
    std::printf("paper_run_%s_wall_s=%.1f\n", r.id.c_str(), r.wall_s);
  }
  std::printf("paper_wall_s=%.1f\n", wall_s);
  std::fflush(stdout);

  std::string csv = paper::csv_header();
  for (const Table& t : tables) csv += paper::render_csv(t);
  const core::Status md_st =
      core::write_file_atomic(o.out_dir + "/paper_tables.md",
                              markdown_report(results, tables, plots, o, wall_s, started, paper_command));
  const core::Status csv_st = core::write_file_atomic(o.out_dir + "/paper_tables.csv", csv);
  for (const core::Status* st : {&md_st, &csv_st}) {
    if (!st->ok()) {
      std::fprintf(stderr, "hwr-bench paper: %s\n", st->message().c_str());
      return 1;
    }
  }
  std::fprintf(stderr, "paper: wrote %s/paper_tables.md, paper_tables.csv and %zu plots\n", o.out_dir.c_str(),
               static_cast<size_t>(
                   std::count_if(plots.begin(), plots.end(), [](const PlotResult& p) { return p.ok; })));
  return g_interrupted ? 130 : 0;
}

}  // namespace

HWR_BENCH_COMMAND(paper, "paper",
                  "the paper's Tables I-IV (and the real datasets' peers) from the other benches run as "
                  "sub-processes, beside the paper's figures; Markdown, CSV, trajectory PNGs [--out DIR] "
                  "[--quick] [--skip a,b] [--duration S] [--run-timeout S] [--dry-run]",
                  run_paper);

}  // namespace hwr::bench
