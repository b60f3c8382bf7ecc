// hwr-eval ae --map DIR: the welding-plate reconstruction error (issue #4 AE) on the fine clouds of a
// map store's welding regions (hwr-robot --map-out DIR --regions truth, recon/region_ae.hpp): every
// ground-truth plate is fitted in the ROI that the region holding it places — the truth seen from
// the region's keyframe, moved with that keyframe's estimated pose — using the fine voxels with
// their point counts as weights. Segments are placed by their T_world_segment (the map without
// segmentation), or with --segmented by the chain of their junctions (with segmentation).
#include "region_ae_eval.hpp"

#include <cstdio>
#include <string>
#include <vector>

#include "hwr/core/tum_trajectory.hpp"
#include "hwr/recon/map_store.hpp"
#include "hwr/recon/region_ae.hpp"

namespace hwr_eval {

namespace {

int usage_region_ae(const char* msg) {
  if (msg != nullptr) std::fprintf(stderr, "hwr-eval ae: %s\n", msg);
  std::fprintf(
      stderr,
      "usage: hwr-eval ae --groundtruth WELD_YAML --map DIR --truth-traj GT [--segmented] [--margin M]\n"
      "  DIR: a map store whose segments hold welding regions (hwr-robot --regions truth);\n"
      "  GT: the run's true T_world_cam (TUM: the sim run's groundtruth.txt, or hwr-robot --gt-out)\n");
  return 2;
}

}  // namespace

int run_region_ae(int argc, char** argv) {
  std::string gt_path, map_dir, traj_path;
  bool segmented = false;
  hwr::recon::RegionAeConfig config;
  for (int i = 2; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--segmented") {
      segmented = true;
      continue;
    }
    if (i + 1 >= argc) return usage_region_ae(("missing value after " + a).c_str());
    const std::string v = argv[++i];
    if (a == "--groundtruth") {
      gt_path = v;
    } else if (a == "--map") {
      map_dir = v;
    } else if (a == "--truth-traj") {
      traj_path = v;
    } else if (a == "--margin") {
      char* end = nullptr;
      config.margin_in_plane_m = std::strtod(v.c_str(), &end);
      if (*end != '\0' || !(config.margin_in_plane_m >= 0 && config.margin_in_plane_m < 1))
        return usage_region_ae("--margin: metres in [0, 1)");
    } else {
      return usage_region_ae(("unknown option " + a).c_str());
    }
  }
  if (gt_path.empty() || map_dir.empty() || traj_path.empty())
    return usage_region_ae("--groundtruth, --map and --truth-traj are required");

  auto gt = hwr::recon::read_weld_groundtruth(gt_path);
  if (!gt.ok()) {
    std::fprintf(stderr, "hwr-eval: %s\n", gt.status().message().c_str());
    return 1;
  }
  auto traj = hwr::core::read_tum_trajectory(traj_path);
  if (!traj.ok()) {
    std::fprintf(stderr, "hwr-eval: %s\n", traj.status().message().c_str());
    return 1;
  }
  auto store = hwr::recon::MapStore::open_existing(map_dir);
  if (!store.ok()) {
    std::fprintf(stderr, "hwr-eval: %s\n", store.status().message().c_str());
    return 1;
  }
  auto list = store->list_segments();
  if (!list.ok()) {
    std::fprintf(stderr, "hwr-eval: %s\n", list.status().message().c_str());
    return 1;
  }
  std::vector<hwr::recon::SegmentRecord> segments;
  for (const auto& s : list.value()) {
    auto rec = store->read_segment(s.segment_id);
    if (!rec.ok()) {
      std::fprintf(stderr, "hwr-eval: %s\n", rec.status().message().c_str());
      return 1;
    }
    rec->points_segment.clear();  // the coarse cloud is not needed
    rec->points_segment.shrink_to_fit();
    segments.push_back(std::move(rec.value()));
  }
  std::vector<hwr::recon::FineSegmentView> views;
  Eigen::Isometry3d chained = Eigen::Isometry3d::Identity();
  for (size_t k = 0; k < segments.size(); ++k) {
    const hwr::recon::SegmentRecord& s = segments[k];
    // With segmentation: segment k placed by the previous one's placement and its junction.
    chained = k == 0 ? s.T_world_segment : chained * s.junction.T_prev_segment_segment;
    views.push_back(
        {&s.weld_regions, &s.fine_points_segment, &s.fine_counts, segmented ? chained : s.T_world_segment});
  }
  auto rep = hwr::recon::compute_region_ae(views, gt.value(), traj.value(), config);
  if (!rep.ok()) {
    std::fprintf(stderr, "hwr-eval: %s\n", rep.status().message().c_str());
    return 1;
  }
  std::printf("AE of the welding regions of %s (%zu segments placed %s) against %s\n", map_dir.c_str(),
              segments.size(), segmented ? "by their junctions" : "by T_world_segment", gt_path.c_str());
  std::printf("  %d regions, %lld fine points; %d of %zu plates in a region\n", rep->regions,
              static_cast<long long>(rep->fine_points), rep->plates_in_regions, gt->plates.size());
  std::printf("  %-24s %-16s %8s %8s %7s %7s %9s %8s %6s  %-27s %s\n", "plate", "region", "L_gt_m", "W_gt_m",
              "dL_mm", "dW_mm", "corner_mm", "inliers", "rms_mm", "edges +x -x +y -y (out, mm)", "notes");
  for (size_t i = 0; i < rep->plates.size(); ++i) {
    const hwr::recon::RegionPlate& rp = rep->plates[i];
    const hwr::recon::PlateAe& a = rep->ae.plates[i];
    const std::string region = rp.region_id < 0 ? "-" : rp.region_label;
    if (!a.seen) {
      std::printf("  %-24s %-16s %8.4f %8.4f   not seen: %s\n", a.name.c_str(), region.c_str(), a.gt_length_m,
                  a.gt_width_m, rp.fit.reason.empty() ? a.reason.c_str() : rp.fit.reason.c_str());
      continue;
    }
    const auto& e = rp.edge_error_mm;
    std::printf("  %-24s %-16s %8.4f %8.4f %+7.2f %+7.2f %9.2f %8d %6.2f  %+6.2f %+6.2f %+6.2f %+6.2f %s\n",
                a.name.c_str(), region.c_str(), a.gt_length_m, a.gt_width_m,
                (a.length_m - a.gt_length_m) * 1e3, (a.width_m - a.gt_width_m) * 1e3, a.mean_corner_error_mm,
                rp.fit.inliers, rp.fit.plane_rms_m * 1e3, e[0], e[1], e[2], e[3],
                rp.fit.at_roi_limit ? "roi-limit" : "");
  }
  std::printf("ae_mm=%.3f\nae_corner_mm=%.3f\nplates_seen=%d\nplates_total=%d\nplates_in_regions=%d\n",
              rep->ae.ae_mm, rep->ae.ae_corner_mm, rep->ae.plates_seen, rep->ae.plates_total,
              rep->plates_in_regions);
  std::printf("regions=%d\nfine_points=%lld\n", rep->regions, static_cast<long long>(rep->fine_points));
  return 0;
}

}  // namespace hwr_eval
