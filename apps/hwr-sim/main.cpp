// hwr-sim: renders a simulated run (scenario preset or YAML file) into a TUM RGB-D style folder
// with EuRoC-style IMU/magnetometer/GNSS files and exact ground truth. See docs/simulator.md.

#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>

#include "hwr/sim/run_writer.hpp"
#include "hwr/sim/scenario.hpp"

namespace {

void usage(std::FILE* f) {
  std::fprintf(
      f,
      "usage: hwr-sim --scenario NAME|FILE.yaml --out DIR [--duration S] [--threads N] [--no-images]\n"
      "  --scenario   a built-in preset (lab, outdoor, lab-revisit, outdoor-revisit) or a YAML file\n"
      "               whose 'base:' names a preset and whose other keys override it\n"
      "  --out        output folder (created if missing)\n"
      "  --duration   simulate only the first S seconds\n"
      "  --threads    render threads (output is identical for any N; default 1)\n"
      "  --no-images  sensor streams, ground truth and calibration only\n");
}

int fail(const std::string& message) {
  std::fprintf(stderr, "hwr-sim: %s\n", message.c_str());
  return 1;
}

bool parse_double(const char* s, double* out) {
  char* end = nullptr;
  *out = std::strtod(s, &end);
  return end != s && *end == '\0';
}

}  // namespace

int main(int argc, char** argv) {
  std::string scenario, out;
  hwr::sim::RunOptions options;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&](const char* name) -> const char* {
      if (i + 1 >= argc) return nullptr;
      (void)name;
      return argv[++i];
    };
    if (a == "--help" || a == "-h") {
      usage(stdout);
      return 0;
    } else if (a == "--scenario") {
      const char* v = value("--scenario");
      if (v == nullptr) return fail("--scenario needs a value (a preset name or a .yaml file)");
      scenario = v;
    } else if (a == "--out") {
      const char* v = value("--out");
      if (v == nullptr) return fail("--out needs a folder");
      out = v;
    } else if (a == "--duration") {
      const char* v = value("--duration");
      if (v == nullptr || !parse_double(v, &options.duration_s) || !(options.duration_s > 0.0)) {
        return fail("--duration needs a number of seconds > 0");
      }
    } else if (a == "--threads") {
      const char* v = value("--threads");
      double n = 0;
      if (v == nullptr || !parse_double(v, &n) || n < 1 || n > 256 || n != static_cast<int>(n)) {
        return fail("--threads needs an integer in 1..256");
      }
      options.threads = static_cast<int>(n);
    } else if (a == "--no-images") {
      options.write_images = false;
    } else {
      usage(stderr);
      return fail("unknown argument '" + a + "'");
    }
  }
  if (scenario.empty() || out.empty()) {
    usage(stderr);
    return fail("--scenario and --out are required");
  }
  auto spec = hwr::sim::load_scenario(scenario);
  if (!spec.ok()) return fail(spec.status().message());
  options.out_dir = out;

  const auto start = std::chrono::steady_clock::now();
  bool printed = false;
  // On a terminal one line is rewritten in place; in a log, one line per 10 % of the frames.
  const bool tty = isatty(STDERR_FILENO) != 0;
  size_t last_decile = SIZE_MAX;
  auto progress = [&](size_t done, size_t total) {
    if (total == 0) return;
    const size_t decile = done * 10 / total;
    if (!tty && decile == last_decile) return;
    last_decile = decile;
    const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    std::fprintf(stderr, "%shwr-sim: frame %zu/%zu (%.0f%%, %.1f s)%s", tty ? "\r" : "", done, total,
                 100.0 * done / total, elapsed, tty ? "" : "\n");
    std::fflush(stderr);
    printed = tty;
  };
  auto run = hwr::sim::write_run(spec.value(), options, progress);
  if (printed) std::fprintf(stderr, "\n");
  if (!run.ok()) return fail(run.status().message());
  const hwr::sim::RunSummary& s = run.value();
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::string files;
  for (const std::string& f : s.files) files += (files.empty() ? "" : " ") + f;
  std::printf(
      "hwr-sim: %s: %zu frames, %.1f s simulated, path %.1f m, %zu joints, %zu imu / %zu mag / %zu gnss "
      "samples, "
      "%.1f s wall -> %s\n",
      s.scenario.c_str(), s.frames, s.simulated_s, s.path_length_m, s.joints, s.imu_samples, s.mag_samples,
      s.gnss_samples, wall, s.out_dir.c_str());
  std::printf("hwr-sim: files: %s\n", files.c_str());
  return 0;
}
