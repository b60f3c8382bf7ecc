// hwr-eval: trajectory accuracy of an estimate against ground truth, both TUM trajectory files.
//   hwr-eval ate GT EST [--max-dt S] [--sim3] [--offset S]
//   hwr-eval rpe GT EST [--delta N] [--delta-unit s|f] [--offset S]
// Prints a readable block, then key=value lines for scripts. Exit: 0 ok, 1 bad input, 2 usage.

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include "hwr/core/tum_trajectory.hpp"
#include "hwr/estimation/trajectory_metrics.hpp"

namespace {

constexpr double kRadToDeg = 180.0 / M_PI;

int usage(const char* msg) {
  if (msg != nullptr) std::fprintf(stderr, "hwr-eval: %s\n", msg);
  std::fprintf(stderr,
               "usage: hwr-eval ate GT EST [--max-dt S] [--sim3] [--offset S]\n"
               "       hwr-eval rpe GT EST [--delta N] [--delta-unit s|f] [--offset S]\n"
               "GT and EST are TUM trajectory files (timestamp tx ty tz qx qy qz qw).\n");
  return 2;
}

bool parse_number(const char* text, double* out) {
  char* end = nullptr;
  const double v = std::strtod(text, &end);
  if (end == text || *end != '\0' || !std::isfinite(v)) return false;
  *out = v;
  return true;
}

void print_stats(const char* title, const hwr::estimation::ErrorStats& s, double unit_scale,
                 const char* unit) {
  std::printf("%s\n", title);
  std::printf(
      "  rmse    %.6f %s\n  mean    %.6f %s\n  median  %.6f %s\n  std     %.6f %s\n  min     %.6f %s\n"
      "  max     %.6f %s\n",
      s.rmse * unit_scale, unit, s.mean * unit_scale, unit, s.median * unit_scale, unit, s.std * unit_scale,
      unit, s.min * unit_scale, unit, s.max * unit_scale, unit);
}

// Prints the one-line error and returns false on failure.
bool load(const std::string& path, std::vector<hwr::core::StampedPose>* out) {
  auto t = hwr::core::read_tum_trajectory(path);
  if (!t.ok()) {
    std::fprintf(stderr, "hwr-eval: %s\n", t.status().message().c_str());
    return false;
  }
  *out = std::move(t).value();
  return true;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2 || std::strcmp(argv[1], "--help") == 0 || std::strcmp(argv[1], "-h") == 0)
    return usage(nullptr);
  const std::string cmd = argv[1];
  if (cmd != "ate" && cmd != "rpe") return usage(("unknown command '" + cmd + "'").c_str());

  std::vector<std::string> positional;
  hwr::estimation::AteOptions ate;
  hwr::estimation::RpeOptions rpe;
  for (int i = 2; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&](double* out) {
      if (i + 1 >= argc || !parse_number(argv[i + 1], out)) return false;
      ++i;
      return true;
    };
    if (a == "--offset") {
      double v = 0;
      if (!value(&v)) return usage("--offset needs a number of seconds");
      ate.offset_s = rpe.offset_s = v;
    } else if (cmd == "ate" && a == "--max-dt") {
      if (!value(&ate.max_dt_s) || !(ate.max_dt_s > 0))
        return usage("--max-dt needs a positive number of seconds");
    } else if (cmd == "ate" && a == "--sim3") {
      ate.sim3 = true;
    } else if (cmd == "rpe" && a == "--delta") {
      if (!value(&rpe.delta) || !(rpe.delta > 0)) return usage("--delta needs a positive number");
    } else if (cmd == "rpe" && a == "--delta-unit") {
      if (i + 1 >= argc) return usage("--delta-unit needs s or f");
      const std::string u = argv[++i];
      if (u == "s") {
        rpe.delta_unit = hwr::estimation::DeltaUnit::kSeconds;
      } else if (u == "f") {
        rpe.delta_unit = hwr::estimation::DeltaUnit::kFrames;
      } else {
        return usage(("--delta-unit must be s or f, got '" + u + "'").c_str());
      }
    } else if (!a.empty() && a[0] == '-') {
      return usage(("unknown option '" + a + "' for " + cmd).c_str());
    } else {
      positional.push_back(a);
    }
  }
  if (positional.size() != 2) return usage("expected two files: GT EST");

  std::vector<hwr::core::StampedPose> gt;
  std::vector<hwr::core::StampedPose> est;
  if (!load(positional[0], &gt) || !load(positional[1], &est)) return 1;

  if (cmd == "ate") {
    auto r = hwr::estimation::compute_ate(gt, est, ate);
    if (!r.ok()) {
      std::fprintf(stderr, "hwr-eval: %s\n", r.status().message().c_str());
      return 1;
    }
    const Eigen::Quaterniond q(r->T_gt_est.linear());
    const Eigen::Vector3d t = r->T_gt_est.translation();
    std::printf("ATE of %s against %s\n", positional[1].c_str(), positional[0].c_str());
    std::printf("  pairs   %zu of %zu estimated, %zu ground-truth poses (max dt %.4f s, offset %.4f s)\n",
                r->pairs, est.size(), gt.size(), ate.max_dt_s, ate.offset_s);
    std::printf("  align   %s: t = [%.6f %.6f %.6f] m, q(xyzw) = [%.6f %.6f %.6f %.6f], scale %.6f\n",
                ate.sim3 ? "Sim(3)" : "SE(3)", t.x(), t.y(), t.z(), q.x(), q.y(), q.z(), q.w(), r->scale);
    print_stats("translational error", r->translation_m, 1.0, "m");
    std::printf("pairs=%zu\n", r->pairs);
    std::printf(
        "ate_rmse_m=%.9f\nate_mean_m=%.9f\nate_median_m=%.9f\nate_std_m=%.9f\nate_min_m=%.9f\n"
        "ate_max_m=%.9f\n",
        r->translation_m.rmse, r->translation_m.mean, r->translation_m.median, r->translation_m.std,
        r->translation_m.min, r->translation_m.max);
    std::printf("scale=%.9f\n", r->scale);
    return 0;
  }

  auto r = hwr::estimation::compute_rpe(gt, est, rpe);
  if (!r.ok()) {
    std::fprintf(stderr, "hwr-eval: %s\n", r.status().message().c_str());
    return 1;
  }
  const char* unit = rpe.delta_unit == hwr::estimation::DeltaUnit::kSeconds ? "s" : "frames";
  std::printf("RPE of %s against %s\n", positional[1].c_str(), positional[0].c_str());
  std::printf("  pairs   %zu over delta %g %s (%zu skipped without ground truth)\n", r->pairs, rpe.delta,
              unit, r->skipped_no_gt);
  print_stats("translational error", r->translation_m, 1.0, "m");
  print_stats("rotational error", r->rotation_rad, kRadToDeg, "deg");
  std::printf("pairs=%zu\n", r->pairs);
  std::printf("rpe_trans_rmse_m=%.9f\nrpe_trans_mean_m=%.9f\nrpe_trans_median_m=%.9f\nrpe_trans_max_m=%.9f\n",
              r->translation_m.rmse, r->translation_m.mean, r->translation_m.median, r->translation_m.max);
  std::printf("rpe_rot_rmse_deg=%.9f\nrpe_rot_mean_deg=%.9f\nrpe_rot_median_deg=%.9f\nrpe_rot_max_deg=%.9f\n",
              r->rotation_rad.rmse * kRadToDeg, r->rotation_rad.mean * kRadToDeg,
              r->rotation_rad.median * kRadToDeg, r->rotation_rad.max * kRadToDeg);
  return 0;
}
