// hwr-eval: accuracy of an estimate against ground truth.
//   hwr-eval ate GT EST [--max-dt S] [--sim3] [--offset S]
//   hwr-eval rpe GT EST [--delta N] [--delta-unit s|f] [--offset S]
//   hwr-eval ae --groundtruth RUN/weld_groundtruth.yaml --cloud FILE [--voxel M] [--align GT EST]
//               [--margin M]
//   hwr-eval ae --groundtruth RUN/weld_groundtruth.yaml --map DIR --truth-traj GT [--segmented]
//               (the welding regions' fine clouds of a map store; region_ae_eval.cpp)
//   hwr-eval map-update --prior P --updated D --groundtruth WELD_YAML --moved NAME[,NAME]
//   (map_update_eval.cpp)
// ate/rpe: trajectories (TUM files). ae: welding-plate reconstruction error of a map cloud (the
// cloud file format of recon/plate_fit.hpp) against the simulator's plate ground truth; --voxel
// says the cloud holds voxel means of a grid of that side in the cloud's frame (recon::VoxelMap),
// --align moves the cloud by the SE(3) alignment of the estimated trajectory EST to GT first, so
// corner errors measure the reconstruction, not the trajectory's global offset.
// Prints a readable block, then key=value lines for scripts. Exit: 0 ok, 1 bad input, 2 usage.

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include "hwr/core/tum_trajectory.hpp"
#include "hwr/estimation/trajectory_metrics.hpp"
#include "hwr/recon/plate_fit.hpp"
#include "map_update_eval.hpp"
#include "region_ae_eval.hpp"

namespace {

constexpr double kRadToDeg = 180.0 / M_PI;

int usage(const char* msg) {
  if (msg != nullptr) std::fprintf(stderr, "hwr-eval: %s\n", msg);
  std::fprintf(
      stderr,
      "usage: hwr-eval ate GT EST [--max-dt S] [--sim3] [--offset S]\n"
      "       hwr-eval rpe GT EST [--delta N] [--delta-unit s|f] [--offset S]\n"
      "       hwr-eval ae --groundtruth WELD_YAML --cloud FILE [--voxel M] [--align GT EST] [--margin M]\n"
      "       hwr-eval ae --groundtruth WELD_YAML --map DIR --truth-traj GT [--segmented] [--margin M]\n"
      "       hwr-eval map-update --prior P --updated D --groundtruth WELD_YAML --moved NAME[,NAME] "
      "[--margin M]\n"
      "GT and EST are TUM trajectory files (timestamp tx ty tz qx qy qz qw); FILE is a cloud of\n"
      "16-byte little-endian records (x y z float32 metres, r g b flags bytes).\n");
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

// hwr-eval ae: fits every ground-truth plate in the cloud and prints the reconstruction error.
int run_ae(int argc, char** argv) {
  std::string gt_path, cloud_path, align_gt, align_est;
  hwr::recon::PlateFitConfig config;
  double margin_m = 0.04;
  for (int i = 2; i < argc; ++i) {
    const std::string a = argv[i];
    auto text = [&](std::string* out) {
      if (i + 1 >= argc) return false;
      *out = argv[++i];
      return true;
    };
    auto number = [&](double* out) {
      if (i + 1 >= argc || !parse_number(argv[i + 1], out)) return false;
      ++i;
      return true;
    };
    if (a == "--groundtruth") {
      if (!text(&gt_path)) return usage("--groundtruth needs a weld_groundtruth.yaml");
    } else if (a == "--cloud") {
      if (!text(&cloud_path)) return usage("--cloud needs a cloud file");
    } else if (a == "--align") {
      if (!text(&align_gt) || !text(&align_est)) return usage("--align needs two TUM files: GT EST");
    } else if (a == "--voxel") {
      if (!number(&config.voxel_m) || !(config.voxel_m > 0))
        return usage("--voxel needs a positive size in metres");
      config.sampling = hwr::recon::CloudSampling::kVoxelMeans;
    } else if (a == "--margin") {
      if (!number(&margin_m) || !(margin_m >= 0))
        return usage("--margin needs a non-negative size in metres");
    } else {
      return usage(("unknown argument '" + a + "' for ae").c_str());
    }
  }
  if (gt_path.empty() || cloud_path.empty()) return usage("ae needs --groundtruth and --cloud");

  auto gt = hwr::recon::read_weld_groundtruth(gt_path);
  if (!gt.ok()) {
    std::fprintf(stderr, "hwr-eval: %s\n", gt.status().message().c_str());
    return 1;
  }
  auto cloud = hwr::recon::read_cloud_file(cloud_path);
  if (!cloud.ok()) {
    std::fprintf(stderr, "hwr-eval: %s\n", cloud.status().message().c_str());
    return 1;
  }
  std::vector<hwr::recon::CloudPoint>& points = cloud.value();
  std::string align_text = "none";
  if (!align_gt.empty()) {
    std::vector<hwr::core::StampedPose> tg, te;
    if (!load(align_gt, &tg) || !load(align_est, &te)) return 1;
    auto ate = hwr::estimation::compute_ate(tg, te);
    if (!ate.ok()) {
      std::fprintf(stderr, "hwr-eval: --align: %s\n", ate.status().message().c_str());
      return 1;
    }
    const Eigen::Isometry3d& T = ate->T_gt_est;
    for (hwr::recon::CloudPoint& p : points) {
      const Eigen::Vector3d q = T * Eigen::Vector3d(p.x_m, p.y_m, p.z_m);
      p.x_m = static_cast<float>(q.x()), p.y_m = static_cast<float>(q.y()), p.z_m = static_cast<float>(q.z());
    }
    config.T_world_grid = T;  // the voxel keys were computed in the estimate's frame
    const Eigen::Quaterniond q(T.linear());
    char buf[256];
    std::snprintf(buf, sizeof(buf),
                  "SE(3) of %zu poses, t = [%.4f %.4f %.4f] m, q(xyzw) = [%.5f %.5f %.5f %.5f]", ate->pairs,
                  T.translation().x(), T.translation().y(), T.translation().z(), q.x(), q.y(), q.z(), q.w());
    align_text = buf;
  }

  std::vector<hwr::recon::PlateFit> fits;
  std::vector<double> rms_mm;
  for (size_t i = 0; i < gt->plates.size(); ++i) {
    const hwr::recon::PlateRoi roi = hwr::recon::plate_roi_from_truth(*gt, i, margin_m);
    auto f = hwr::recon::fit_plate(points.data(), points.size(), roi, config);
    if (!f.ok()) {
      std::fprintf(stderr, "hwr-eval: plate '%s': %s\n", gt->plates[i].name.c_str(),
                   f.status().message().c_str());
      return 1;
    }
    fits.push_back(*f);
  }
  auto rep = hwr::recon::compute_ae(fits, *gt);
  if (!rep.ok()) {
    std::fprintf(stderr, "hwr-eval: %s\n", rep.status().message().c_str());
    return 1;
  }
  std::printf("AE of %s against %s\n", cloud_path.c_str(), gt_path.c_str());
  std::printf("  cloud   %zu points, %s\n", points.size(),
              config.sampling == hwr::recon::CloudSampling::kVoxelMeans
                  ? ("voxel means of " + std::to_string(config.voxel_m) + " m").c_str()
                  : "raw points");
  std::printf("  align   %s\n", align_text.c_str());
  std::printf("  %-24s %5s %8s %8s %8s %8s %7s %7s %9s %8s %6s  %s\n", "plate", "face", "L_gt_m", "W_gt_m",
              "L_m", "W_m", "dL_mm", "dW_mm", "corner_mm", "inliers", "rms_mm", "notes");
  for (size_t i = 0; i < rep->plates.size(); ++i) {
    const hwr::recon::PlateAe& a = rep->plates[i];
    if (!a.seen) {
      std::printf("  %-24s %5s %8.4f %8.4f   not seen: %s\n", a.name.c_str(), "-", a.gt_length_m,
                  a.gt_width_m, a.reason.c_str());
      continue;
    }
    // Notes: an edge stopped at the ROI boundary (the face merges with its surroundings there);
    // voxel edges left at their band-mean place (too few boundary voxels).
    std::string notes;
    if (fits[i].at_roi_limit) notes += " roi-limit";
    if (fits[i].edges_from_band_mean > 0)
      notes += " band-mean-edges=" + std::to_string(fits[i].edges_from_band_mean);
    std::printf("  %-24s %5s %8.4f %8.4f %8.4f %8.4f %7.2f %7.2f %9.2f %8d %6.2f %s\n", a.name.c_str(),
                fits[i].face_sign > 0 ? "+z" : "-z", a.gt_length_m, a.gt_width_m, a.length_m, a.width_m,
                a.length_error_mm, a.width_error_mm, a.mean_corner_error_mm, fits[i].inliers,
                fits[i].plane_rms_m * 1e3, notes.c_str());
  }
  std::printf("ae_mm=%.3f\nae_corner_mm=%.3f\nplates_seen=%d\nplates_total=%d\n", rep->ae_mm,
              rep->ae_corner_mm, rep->plates_seen, rep->plates_total);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2 || std::strcmp(argv[1], "--help") == 0 || std::strcmp(argv[1], "-h") == 0)
    return usage(nullptr);
  const std::string cmd = argv[1];
  if (cmd == "ae") {
    for (int i = 2; i < argc; ++i)
      if (std::strcmp(argv[i], "--map") == 0) return hwr_eval::run_region_ae(argc, argv);
    return run_ae(argc, argv);
  }
  if (cmd == "map-update") return hwr_eval::run_map_update(argc, argv);
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
