// `hwr-bench segmentation` (issue #4; paper Table III): the whole pipeline — pose estimation, keyframe
// clouds, the active local map, segment cuts with ORB + NDT junctions — on the sim sequences, then
//  - ATE without segmentation (the estimator's trajectory) and with it (each segment's part of the
//    trajectory carried through the chain of refined junctions instead of the odometry), and
//  - AE of the welding plates on the map assembled without (T_world_segment) and with (chained
//    junctions) segmentation: on the fine clouds of the welding regions (the simulator's joints
//    stand in for detections, recon/truth_weld_regions.hpp; each plate measured in the ROI its
//    detection placed, recon/region_ae.hpp) — the AE keys — and on the coarse map with the truth's
//    ROIs as they are (seg_ae_coarse_mm_*),
// printed side by side; the error of every junction against the true relative pose of its two
// keyframes; mapping time per keyframe and tracking time per frame binned by total map size; and
// the process's resident memory at every segment close, less the points this bench keeps for its AE
// (flat after the first segment when memory is bounded).
//
//   hwr-bench segmentation [--sequences lab,outdoor] [--duration S] [--config FILE]
//                          [--store DIR]  (also write the segments to a map store there)
//                          [--regions truth|geometry]
// --regions geometry: the welding regions come from the geometric seam detector (detect/) on each
// keyframe's depth at its estimated pose, as in `hwr-robot --regions geometry`, instead of the
// simulator's joints; the AE keys are then prefixed "detected_" (the AE on the detected regions).

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <memory>
#include <numeric>
#include <sstream>
#include <string>
#include <vector>

#include "bench_command.hpp"
#include "bench_sequences.hpp"
#include "hwr/core/config.hpp"
#include "hwr/core/malloc_policy.hpp"
#include "hwr/estimation/estimator_config.hpp"
#include "hwr/estimation/offline_run.hpp"
#include "hwr/estimation/trajectory_metrics.hpp"
#include "hwr/recon/local_mapper.hpp"
#include "hwr/recon/local_mapper_config.hpp"
#include "hwr/recon/plate_fit.hpp"
#include "hwr/recon/region_ae.hpp"
#include "hwr/recon/segment_writer.hpp"
#include "hwr/detect/geometric_seam_detector.hpp"
#include "hwr/recon/truth_weld_regions.hpp"

namespace hwr::bench {
namespace {

double rss_mib() {
  std::ifstream f("/proc/self/status");
  std::string key;
  while (f >> key) {
    if (key == "VmRSS:") {
      double kib = 0;
      f >> kib;
      return kib / 1024.0;
    }
    std::getline(f, key);
  }
  return 0;
}

constexpr double kRoiMarginM = 0.3;
// The truth "detector": joint boxes inflated by 5 cm, reported when the joint's centre is within 4 m
// (the fine cloud takes pixels up to 3.5 m).
constexpr double kJointBoxMarginM = 0.05;
constexpr double kDetectMinRangeM = 0.3, kDetectMaxRangeM = 4.0;

double mean(const std::vector<double>& v) {
  return v.empty() ? 0 : std::accumulate(v.begin(), v.end(), 0.0) / static_cast<double>(v.size());
}

double angle_deg(const Eigen::Isometry3d& T) { return Eigen::AngleAxisd(T.linear()).angle() * 180.0 / M_PI; }

// What the bench keeps of a closed segment: its frame, junction, time span and, for AE, the points.
struct SegmentSummary {
  uint32_t id = 0;
  Eigen::Isometry3d T_world_segment;
  recon::JunctionRecord junction;
  int64_t t_first_ns = 0;
  double travelled_m = 0;
  size_t points = 0;
  Eigen::Isometry3d T_world_a = Eigen::Isometry3d::Identity();  // the segment's last keyframe
  int64_t t_last_ns = 0;
  std::vector<recon::CloudPoint> points_segment;
  // The fine cloud of the welding regions (the simulator's joints as detections).
  std::vector<recon::StoredWeldRegion> weld_regions;
  std::vector<recon::CloudPoint> fine_points_segment;
  std::vector<uint32_t> fine_counts;
  double rss_mib_at_close = 0;
  bool after_run = false;  // closed by the end-of-run flush, after the full bundle adjustment
};

// Oriented boxes around the weld plates (world frame), inflated: the bench keeps only the map points
// inside them, so its own memory stays flat while it measures the robot's.
struct PlateRoi {
  Eigen::Isometry3d T_plate_world;
  Eigen::Vector3d half_m;
};

class BenchSink final : public recon::SegmentSink {
 public:
  recon::StoreSegmentWriter* writer = nullptr;
  std::vector<PlateRoi> rois;
  bool run_ended = false;
  std::vector<SegmentSummary> segments;
  size_t retained_bytes = 0;  // the summaries' point arrays so far
  void take(recon::SegmentRecord&& seg) override {
    SegmentSummary s;
    s.id = seg.segment_id;
    s.T_world_segment = seg.T_world_segment;
    s.junction = seg.junction;
    s.t_first_ns = seg.t_first_ns;
    s.travelled_m = seg.travelled_m;
    s.points = seg.points_segment.size();
    if (!seg.keyframes.empty()) {
      s.T_world_a = seg.keyframes.back().T_world_cam;
      s.t_last_ns = seg.keyframes.back().t_ns;
    }
    s.weld_regions = seg.weld_regions;
    s.fine_points_segment = seg.fine_points_segment;
    s.fine_counts = seg.fine_counts;
    const Eigen::Isometry3d T = seg.T_world_segment;
    for (const auto& p : seg.points_segment) {
      const Eigen::Vector3d w = T * Eigen::Vector3d(p.x_m, p.y_m, p.z_m);
      for (const PlateRoi& r : rois) {
        const Eigen::Vector3d q = r.T_plate_world * w;
        if (std::abs(q.x()) <= r.half_m.x() && std::abs(q.y()) <= r.half_m.y() &&
            std::abs(q.z()) <= r.half_m.z()) {
          s.points_segment.push_back(p);
          break;
        }
      }
    }
    if (writer != nullptr) writer->take(std::move(seg));
    // The robot's memory: the process's, less what this bench keeps of the segments for its AE.
    retained_bytes += s.points_segment.capacity() * sizeof(recon::CloudPoint) +
                      s.fine_points_segment.capacity() * sizeof(recon::CloudPoint) +
                      s.fine_counts.capacity() * sizeof(uint32_t) +
                      s.weld_regions.capacity() * sizeof(recon::StoredWeldRegion);
    s.rss_mib_at_close = rss_mib() - static_cast<double>(retained_bytes) / (1024.0 * 1024.0);
    s.after_run = run_ended;
    segments.push_back(std::move(s));
  }
};

// AE (hwr-eval ae's definition) of the plates on a map whose segment k is placed by pose[k].
double ae_of(const std::vector<SegmentSummary>& segs, const std::vector<Eigen::Isometry3d>& T_world_segment,
             const recon::WeldGroundTruth& gt, double* corner_mm, int* seen) {
  std::vector<recon::CloudPoint> world;
  for (size_t k = 0; k < segs.size(); ++k) {
    const Eigen::Isometry3f T = T_world_segment[k].cast<float>();
    for (const auto& p : segs[k].points_segment) {
      recon::CloudPoint q = p;
      const Eigen::Vector3f w = T * Eigen::Vector3f(p.x_m, p.y_m, p.z_m);
      q.x_m = w.x();
      q.y_m = w.y();
      q.z_m = w.z();
      world.push_back(q);
    }
  }
  std::vector<recon::PlateFit> fits;
  for (size_t i = 0; i < gt.plates.size(); ++i) {
    // Voxel means of several segment grids: fitted as raw points (plate_fit.hpp's single-grid
    // voxel model does not apply across segments).
    auto fit = recon::fit_plate(world.data(), world.size(), recon::plate_roi_from_truth(gt, i),
                                recon::PlateFitConfig{});
    fits.push_back(fit.ok() ? fit.value() : recon::PlateFit{});
  }
  auto report = recon::compute_ae(fits, gt);
  if (!report.ok()) return NAN;
  *corner_mm = report->ae_corner_mm;
  *seen = report->plates_seen;
  return report->ae_mm;
}

// AE on the fine clouds of the welding regions (recon/region_ae.hpp), segment k placed by pose[k].
bool region_ae_of(const std::vector<SegmentSummary>& segs,
                  const std::vector<Eigen::Isometry3d>& T_world_segment, const recon::WeldGroundTruth& gt,
                  const std::vector<core::StampedPose>& truth, recon::RegionAeReport* out) {
  std::vector<recon::FineSegmentView> views;
  for (size_t k = 0; k < segs.size(); ++k)
    views.push_back(
        {&segs[k].weld_regions, &segs[k].fine_points_segment, &segs[k].fine_counts, T_world_segment[k]});
  auto r = recon::compute_region_ae(views, gt, truth, recon::RegionAeConfig{});
  if (!r.ok()) {
    std::fprintf(stderr, "hwr-bench segmentation: region AE: %s\n", r.status().message().c_str());
    return false;
  }
  *out = r.value();
  return true;
}

struct Bin {
  const char* name;
  double max_points;
  std::vector<double> map_ms, frame_ms;
};

int run_segmentation(int argc, char** argv) {
  // The robot's heap policy (hwr-robot sets it too): the RSS figures are the robot's.
  if (const auto st = core::fix_malloc_mmap_threshold(); !st.ok()) {
    std::fprintf(stderr, "hwr-bench segmentation: %s\n", st.message().c_str());
    return 1;
  }
  std::string sequences = "lab,outdoor", store_dir, regions = "truth";
  double duration_s = 0;
  estimation::PoseEstimatorConfig est_cfg;
  recon::LocalMapperConfig map_cfg;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--sequences" && i + 1 < argc) {
      sequences = argv[++i];
    } else if (a == "--duration" && i + 1 < argc) {
      duration_s = std::atof(argv[++i]);
    } else if (a == "--store" && i + 1 < argc) {
      store_dir = argv[++i];
    } else if (a == "--regions" && i + 1 < argc) {
      regions = argv[++i];
      if (regions != "truth" && regions != "geometry") {
        std::fprintf(stderr, "hwr-bench segmentation: --regions: expected truth or geometry, got '%s'\n",
                     regions.c_str());
        return 2;
      }
    } else if (a == "--config" && i + 1 < argc) {
      auto doc = core::ConfigDocument::load_file(argv[++i]);
      core::Status st = doc.status();
      if (doc.ok()) {
        estimation::read_estimator_config(doc->root().child("estimation"), &est_cfg);
        recon::read_local_mapper_config(doc->root().child("map"), &map_cfg);
        st = doc->finish();
      }
      if (!st.ok()) {
        std::fprintf(stderr, "hwr-bench segmentation: --config: %s\n", st.message().c_str());
        return 2;
      }
    } else {
      std::fprintf(stderr, "hwr-bench segmentation: unknown option '%s'\n", a.c_str());
      return 2;
    }
  }
  // As hwr-robot: the seam detector's boxes hold what one keyframe saw, a region grows to hold them all.
  const bool detected = regions == "geometry";
  if (detected) map_cfg.fine.grow_to_cover = true;
  const std::string key_prefix = detected ? "detected_" : "";
  std::vector<std::string> names;
  std::stringstream ss(sequences);
  for (std::string n; std::getline(ss, n, ',');)
    if (!n.empty()) names.push_back(n);

  std::vector<std::string> keys;
  double worst_ate_diff_pct = -1e9, worst_ae_diff_pct = -1e9;  // signed maxima over the sequences
  std::vector<double> ae_all;
  char line0[256];
  Bin bins[] = {
      {"< 0.1M", 1e5, {}, {}}, {"0.1M-1M", 1e6, {}, {}}, {"1M-10M", 1e7, {}, {}}, {">= 10M", 1e300, {}, {}}};
  for (const std::string& name : names) {
    auto seq = open_sequence(name, duration_s);
    if (!seq.ok()) {
      std::fprintf(stderr, "hwr-bench segmentation: %s: %s\n", name.c_str(), seq.status().message().c_str());
      return 1;
    }
    auto mapper =
        recon::LocalMapper::create(map_cfg, seq->log.info.intrinsics, est_cfg.tracker.orb.max_features);
    if (!mapper.ok()) {
      std::fprintf(stderr, "hwr-bench segmentation: %s\n", mapper.status().message().c_str());
      return 2;
    }
    BenchSink sink;
    recon::WeldGroundTruth gt;
    std::vector<recon::TruthJointBox> joint_boxes;
#if HWR_WITH_SIM
    {
      auto parsed = recon::parse_weld_groundtruth(seq->weld_truth_yaml, name + " weld truth");
      if (!parsed.ok()) {
        std::fprintf(stderr, "hwr-bench segmentation: %s\n", parsed.status().message().c_str());
        return 1;
      }
      gt = std::move(parsed.value());
    }
    joint_boxes = recon::truth_joint_boxes(gt, kJointBoxMarginM);
    for (const auto& plate : seq->weld_truth_world.plates) {
      sink.rois.push_back(
          {plate.T_scene_plate.inverse(), plate.size_m / 2 + Eigen::Vector3d::Constant(kRoiMarginM)});
    }
#endif
    std::unique_ptr<recon::StoreSegmentWriter> writer;
    if (!store_dir.empty()) {
      recon::StoreMetadata meta;
      meta.run_id = "bench-" + name;
      meta.intrinsics = seq->log.info.intrinsics;
      auto store = recon::MapStore::open(store_dir + "/" + name, meta);
      if (!store.ok()) {
        std::fprintf(stderr, "hwr-bench segmentation: --store: %s\n", store.status().message().c_str());
        return 1;
      }
      writer = std::make_unique<recon::StoreSegmentWriter>(std::move(store.value()));
      sink.writer = writer.get();
    }
    std::vector<double> total_points_at_frame;
    std::vector<std::pair<double, double>> map_ms_at_points;  // (ms, total points) per update that fused
    estimation::OfflineRunOptions opt;
    opt.estimator = est_cfg;
    std::map<int64_t, Eigen::Isometry3d> truth_at_frame;
    for (const auto& p : seq->groundtruth) truth_at_frame[p.t_ns] = p.T_world_body;
    int detected_upto = -1;  // newest keyframe the "detector" has looked at
    std::vector<recon::WeldRegion> detections;
    std::unique_ptr<detect::GeometricSeamDetector> seam_detector;
    const detect::GeometricSeamConfig seam_config;
    detect::DetectionList seams(seam_config.max_detections);
    if (detected) {
      auto d = detect::GeometricSeamDetector::create(seam_config, seq->log.info.intrinsics);
      if (!d.ok()) {
        std::fprintf(stderr, "hwr-bench segmentation: %s\n", d.status().message().c_str());
        return 2;
      }
      seam_detector = std::move(d.value());
    }
    opt.after_frame = [&](size_t, const estimation::PoseEstimator& e) {
      // Welding regions, placed by the mapper with each new keyframe's estimated pose: the simulator's
      // joints seen from the keyframe's true pose (recon/truth_weld_regions.hpp), or the seam
      // detector's on its depth.
      const estimation::KeyframeStore& kfs = e.tracker().keyframes();
      for (int id = std::max(detected_upto + 1, kfs.oldest_id()); !kfs.empty() && id <= kfs.newest_id();
           ++id) {
        const estimation::Keyframe* kf = kfs.get(id);
        if (kf == nullptr) continue;
        if (seam_detector) {
          const cv::Mat* depth = kfs.depth_m(id);
          if (depth == nullptr || depth->empty()) continue;
          detect::KeyframeView view;
          view.keyframe_id = id;
          view.t_ns = kf->t_ns;
          view.K = seq->log.info.intrinsics;
          view.bgr = kfs.bgr(id);
          view.depth_m = depth;
          view.T_world_cam = kf->T_world_cam;
          if (!seam_detector->detect(view, &seams).ok()) continue;
          for (int i = 0; i < seams.size(); ++i)
            if (!seams[i].support_only)  // a region only where the detector is confident
              mapper->add_weld_region(recon::weld_region_from_detection(seams[i]), kf->T_world_cam);
          continue;
        }
        const auto truth = truth_at_frame.find(kf->t_ns);
        if (truth == truth_at_frame.end()) continue;
        recon::truth_detections(joint_boxes, truth->second, seq->log.info.intrinsics, kDetectMinRangeM,
                                kDetectMaxRangeM, id, kf->t_ns, &detections);
        for (const recon::WeldRegion& d : detections) mapper->add_weld_region(d, kf->T_world_cam);
      }
      if (!kfs.empty()) detected_upto = std::max(detected_upto, kfs.newest_id());
      const uint64_t fused = mapper->counters().keyframes_fused;
      const auto t0 = std::chrono::steady_clock::now();
      mapper->update(e.tracker().keyframes(), &sink);
      const double ms =
          std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
      const double total =
          static_cast<double>(mapper->counters().points_closed) + mapper->active_map().size();
      if (mapper->counters().keyframes_fused != fused) map_ms_at_points.emplace_back(ms, total);
      total_points_at_frame.push_back(total);
    };
    opt.at_end = [&](const estimation::PoseEstimator& e) {
      sink.run_ended = true;
      mapper->finish(e.tracker().keyframes(), &sink);
    };
    auto run = estimation::run_offline(seq->log, opt);
    if (!run.ok()) {
      std::fprintf(stderr, "hwr-bench segmentation: %s: %s\n", name.c_str(), run.status().message().c_str());
      return 1;
    }
    if (writer) writer->drain();
    const auto& segs = sink.segments;

    // The trajectory with segmentation: segment k's frames carried by D_k = C_k T_world_segment_k^-1,
    // C_0 = T_world_segment_0, C_k = C_{k-1} T_prev_segment_segment_k (the refined junctions).
    std::vector<Eigen::Isometry3d> C(segs.size()), D(segs.size());
    for (size_t k = 0; k < segs.size(); ++k) {
      C[k] = k == 0 ? segs[0].T_world_segment : C[k - 1] * segs[k].junction.T_prev_segment_segment;
      D[k] = C[k] * segs[k].T_world_segment.inverse();
    }
    // Segments, junctions and T_world_segment hold the live poses (before the end-of-run full bundle
    // adjustment), so both ATEs are taken on the trajectory before it.
    const std::vector<core::StampedPose>& traj_live = run->trajectory_before_full_ba;
    std::vector<core::StampedPose> traj_seg = traj_live;
    size_t k = 0;
    for (auto& p : traj_seg) {
      while (k + 1 < segs.size() && p.t_ns >= segs[k + 1].t_first_ns) ++k;
      if (!segs.empty()) p.T_world_body = D[k] * p.T_world_body;
    }
    auto ate_without = estimation::compute_ate(seq->groundtruth, traj_live, estimation::AteOptions{});
    auto ate_with = estimation::compute_ate(seq->groundtruth, traj_seg, estimation::AteOptions{});
    if (!ate_without.ok() || !ate_with.ok()) {
      std::fprintf(stderr, "hwr-bench segmentation: %s: ATE failed\n", name.c_str());
      return 1;
    }
    const double a0 = ate_without->translation_m.rmse, a1 = ate_with->translation_m.rmse;
    // Signed, as the paper reports it: positive when segmentation makes the trajectory worse.
    const double diff_pct = 100.0 * (a1 - a0) / a0;
    worst_ate_diff_pct = std::max(worst_ate_diff_pct, diff_pct);

    // Junctions against the truth.
    std::map<int64_t, Eigen::Isometry3d> gt_at;
    for (const auto& p : seq->groundtruth) gt_at[p.t_ns] = p.T_world_body;
    std::printf("\n%s: %zu frames, %.0f m, %zu segments, %llu keyframes fused\n", name.c_str(), run->frames,
                seq->path_length_m, segs.size(),
                static_cast<unsigned long long>(mapper->counters().keyframes_fused));
    std::printf("%4s %7s %9s %8s %6s %5s %6s %11s %11s %11s %11s %11s %11s\n", "cut", "travel", "points",
                "inliers", "ndt", "fused", "RSS", "junct [mm]", "junct [deg]", "meas [mm]", "meas [deg]",
                "odom [mm]", "odom [deg]");
    // Junction errors: the stored (fused) junction, the ORB/NDT measurement alone, the odometry.
    std::vector<double> junction_mm, odometry_mm, measured_mm, junction_deg, odometry_deg, measured_deg;
    for (size_t s = 0; s < segs.size(); ++s) {
      const auto& j = segs[s].junction;
      double ej_mm = NAN, ej_deg = NAN, eo_mm = NAN, eo_deg = NAN, em_mm = NAN, em_deg = NAN;
      if (s > 0) {
        // Keyframe times: a is the previous segment's last keyframe, b this segment's first.
        const SegmentSummary& prev = segs[s - 1];
        const Eigen::Isometry3d T_prevseg_a = prev.T_world_segment.inverse() * prev.T_world_a;
        const Eigen::Isometry3d T_a_b_ref = T_prevseg_a.inverse() * j.T_prev_segment_segment;
        const Eigen::Isometry3d T_a_b_odo = T_prevseg_a.inverse() * j.T_prev_segment_segment_odometry;
        const Eigen::Isometry3d T_a_b_meas = T_prevseg_a.inverse() * j.T_prev_segment_segment_measured;
        const auto ga = gt_at.find(prev.t_last_ns), gb = gt_at.find(segs[s].t_first_ns);
        if (ga != gt_at.end() && gb != gt_at.end()) {
          const Eigen::Isometry3d T_a_b_true = ga->second.inverse() * gb->second;
          const Eigen::Isometry3d er = T_a_b_true.inverse() * T_a_b_ref,
                                  eo = T_a_b_true.inverse() * T_a_b_odo;
          ej_mm = er.translation().norm() * 1e3;
          ej_deg = angle_deg(er);
          eo_mm = eo.translation().norm() * 1e3;
          eo_deg = angle_deg(eo);
          const Eigen::Isometry3d em = T_a_b_true.inverse() * T_a_b_meas;
          em_mm = em.translation().norm() * 1e3;
          em_deg = angle_deg(em);
          junction_mm.push_back(ej_mm);
          odometry_mm.push_back(eo_mm);
          measured_mm.push_back(em_mm);
          junction_deg.push_back(ej_deg);
          odometry_deg.push_back(eo_deg);
          measured_deg.push_back(em_deg);
        }
      }
      std::printf("%4zu %7.2f %9zu %8d %6s %5s %6.0f %11.1f %11.3f %11.1f %11.3f %11.1f %11.3f\n", s,
                  segs[s].travelled_m, segs[s].points, j.orb_inliers,
                  s == 0 ? "-" : (j.ndt_converged ? "conv" : "no"), s == 0 ? "-" : (j.fused ? "yes" : "no"),
                  segs[s].rss_mib_at_close, ej_mm, ej_deg, em_mm, em_deg, eo_mm, eo_deg);
    }
    std::printf("ATE without segmentation %.4f m, with %.4f m: difference %.2f %% (paper: 2.3-3.75 %%)\n", a0,
                a1, diff_pct);
#if HWR_WITH_SIM
    std::vector<Eigen::Isometry3d> T_without(segs.size());
    for (size_t s = 0; s < segs.size(); ++s) T_without[s] = segs[s].T_world_segment;
    double corner0 = NAN, corner1 = NAN;
    int seen0 = 0, seen1 = 0;
    const double ae0 = ae_of(segs, T_without, gt, &corner0, &seen0);
    const double ae1 = ae_of(segs, C, gt, &corner1, &seen1);
    const double ae_diff_pct = 100.0 * (ae1 - ae0) / ae0;  // signed, positive = worse with segmentation
    // The welding regions' fine clouds (the AE of issue #4): each plate in the ROI its detection
    // placed, with and without segmentation.
    recon::RegionAeReport fine0, fine1;
    if (!region_ae_of(segs, T_without, gt, seq->groundtruth, &fine0) ||
        !region_ae_of(segs, C, gt, seq->groundtruth, &fine1))
      return 1;
    const double fae0 = fine0.ae.ae_mm, fae1 = fine1.ae.ae_mm;
    const double fae_diff_pct = 100.0 * (fae1 - fae0) / fae0;  // signed, positive = worse with segmentation
    worst_ae_diff_pct =
        std::isfinite(fae_diff_pct) ? std::max(worst_ae_diff_pct, fae_diff_pct) : worst_ae_diff_pct;
    ae_all.push_back(fae0);
    std::printf("\n%-22s %8s %9s %9s %9s %10s  %s\n", "plate", "region", "dL [mm]", "dW [mm]", "corner",
                "fine pts", "(welding regions, without segmentation)");
    for (size_t i = 0; i < fine0.plates.size(); ++i) {
      const recon::RegionPlate& rp = fine0.plates[i];
      const recon::PlateAe& pa = fine0.ae.plates[i];
      if (!pa.seen) {
        std::printf("%-22s %8s %s\n", rp.plate.c_str(),
                    rp.region_label.empty() ? "-" : rp.region_label.c_str(),
                    pa.reason.empty() ? rp.fit.reason.c_str() : pa.reason.c_str());
        continue;
      }
      std::printf("%-22s %8s %+9.2f %+9.2f %9.2f %10d\n", rp.plate.c_str(), rp.region_label.c_str(),
                  (pa.length_m - pa.gt_length_m) * 1e3, (pa.width_m - pa.gt_width_m) * 1e3,
                  pa.mean_corner_error_mm, rp.fit.inliers);
    }
    std::printf(
        "AE on the welding regions' fine clouds without segmentation %.2f mm, with %.2f mm: difference %.2f "
        "%%; corners %.2f / %.2f mm; plates seen %d / %zu; %d regions, %lld fine points (paper: lab 80 / 83 "
        "mm, "
        "outdoor 208 / 214 mm)\n",
        fae0, fae1, fae_diff_pct, fine0.ae.ae_corner_mm, fine1.ae.ae_corner_mm, fine0.ae.plates_seen,
        gt.plates.size(), fine0.regions, static_cast<long long>(fine0.fine_points));
    std::printf(
        "AE on the coarse map (%.0f mm voxels, the truth's ROIs without local placement) without %.2f mm, "
        "with "
        "%.2f mm: difference %.2f %%; plates seen %d / %zu\n",
        map_cfg.voxels.voxel_m * 1e3, ae0, ae1, ae_diff_pct, seen0, gt.plates.size());
    std::snprintf(line0, sizeof(line0), "%sseg_ae_mm_%s_without=%.3f", key_prefix.c_str(), name.c_str(),
                  fae0);
    keys.push_back(line0);
    std::snprintf(line0, sizeof(line0), "%sseg_ae_mm_%s_with=%.3f", key_prefix.c_str(), name.c_str(), fae1);
    keys.push_back(line0);
    std::snprintf(line0, sizeof(line0), "%sseg_ae_corner_mm_%s_without=%.3f", key_prefix.c_str(),
                  name.c_str(), fine0.ae.ae_corner_mm);
    keys.push_back(line0);
    std::snprintf(line0, sizeof(line0), "%splates_seen_%s=%d/%zu", key_prefix.c_str(), name.c_str(),
                  fine0.ae.plates_seen, gt.plates.size());
    keys.push_back(line0);
    std::snprintf(line0, sizeof(line0), "%sfine_points_%s=%lld", key_prefix.c_str(), name.c_str(),
                  static_cast<long long>(fine0.fine_points));
    keys.push_back(line0);
    std::snprintf(line0, sizeof(line0), "seg_ae_coarse_mm_%s_without=%.3f", name.c_str(), ae0);
    keys.push_back(line0);
    std::snprintf(line0, sizeof(line0), "seg_ae_coarse_mm_%s_with=%.3f", name.c_str(), ae1);
    keys.push_back(line0);
#endif
    char line[256];
    std::snprintf(line, sizeof(line), "seg_ate_m_%s_without=%.5f", name.c_str(), a0);
    keys.push_back(line);
    std::snprintf(line, sizeof(line), "seg_ate_m_%s_with=%.5f", name.c_str(), a1);
    keys.push_back(line);
    std::snprintf(line, sizeof(line), "seg_ate_diff_pct_%s=%.3f", name.c_str(), diff_pct);
    keys.push_back(line);
    std::snprintf(line, sizeof(line), "segments_%s=%zu", name.c_str(), segs.size());
    keys.push_back(line);
    std::snprintf(line, sizeof(line), "junction_err_mm_%s_mean=%.2f", name.c_str(), mean(junction_mm));
    keys.push_back(line);
    std::snprintf(line, sizeof(line), "junction_err_mm_%s_max=%.2f", name.c_str(),
                  junction_mm.empty() ? 0.0 : *std::max_element(junction_mm.begin(), junction_mm.end()));
    keys.push_back(line);
    std::snprintf(line, sizeof(line), "junction_odometry_err_mm_%s_mean=%.2f", name.c_str(),
                  mean(odometry_mm));
    keys.push_back(line);
    std::snprintf(line, sizeof(line), "junction_measured_err_mm_%s_mean=%.2f", name.c_str(),
                  mean(measured_mm));
    keys.push_back(line);
    std::snprintf(line, sizeof(line), "junction_err_deg_%s_mean=%.4f", name.c_str(), mean(junction_deg));
    keys.push_back(line);
    std::snprintf(line, sizeof(line), "junction_measured_err_deg_%s_mean=%.4f", name.c_str(),
                  mean(measured_deg));
    keys.push_back(line);
    std::snprintf(line, sizeof(line), "junction_odometry_err_deg_%s_mean=%.4f", name.c_str(),
                  mean(odometry_deg));
    keys.push_back(line);
    if (segs.size() >= 3) {
      // Closes during the run; those of the end-of-run flush come after the full bundle adjustment,
      // whose problem is allocated then and is not the mapper's.
      double peak = 0;
      for (size_t s = 1; s < segs.size(); ++s)
        if (!segs[s].after_run) peak = std::max(peak, segs[s].rss_mib_at_close);
      std::snprintf(line, sizeof(line), "rss_growth_pct_%s=%.2f", name.c_str(),
                    100.0 * (peak - segs[0].rss_mib_at_close) / segs[0].rss_mib_at_close);
      keys.push_back(line);
    }

    // Time against map size.
    for (const auto& [ms, pts] : map_ms_at_points) {
      for (Bin& b : bins)
        if (pts < b.max_points) {
          b.map_ms.push_back(ms);
          break;
        }
    }
    for (size_t i = 0; i < run->timings.size() && i < total_points_at_frame.size(); ++i) {
      if (run->timings[i].state == estimation::TrackState::kWaiting) continue;
      for (Bin& b : bins)
        if (total_points_at_frame[i] < b.max_points) {
          b.frame_ms.push_back(run->timings[i].total_ns * 1e-6);
          break;
        }
    }
  }
  std::printf("\n%-10s %12s %14s %12s\n", "map size", "keyframes", "map ms / kf", "frame ms");
  for (const Bin& b : bins) {
    std::printf("%-10s %12zu %14.2f %12.2f\n", b.name, b.map_ms.size(), mean(b.map_ms), mean(b.frame_ms));
  }
  for (const auto& k : keys) std::printf("%s\n", k.c_str());
  std::printf("seg_ate_diff_pct=%.3f\n", worst_ate_diff_pct);
  std::printf("%sseg_ae_diff_pct=%.3f\n", key_prefix.c_str(), worst_ae_diff_pct);
  std::printf("%sae_mm=%.3f\n", key_prefix.c_str(), mean(ae_all));
  return 0;
}

}  // namespace

HWR_BENCH_COMMAND(
    segmentation, "segmentation",
    "map segmentation (paper Table III): ATE and AE with/without segmentation, junction errors, "
    "time and memory against map size [--sequences lab,outdoor] [--duration S] [--config FILE] "
    "[--store DIR] [--regions truth|geometry]",
    run_segmentation);

}  // namespace hwr::bench
