// hwr-bench detect: the geometric seam detector (issue #7) on the simulator's scenarios, per keyframe
// and fused over the keyframes, against the seams of the simulator's ground truth.
//
//   hwr-bench detect [--sequences lab,outdoor] [--step N] [--duration S] [--max-range M]
//                    [--area-sampling]
//
// Every --step-th frame is a keyframe here: its depth image (rendered with the simulator's stereo
// noise) goes to GeometricSeamDetector at the frame's true pose (the detector's accuracy, not the
// tracker's). The true seams a frame sees are the parts visible_seam_part() finds (in the image, in
// range, from the fillet's open side, not hidden); detections are matched to them by score_seams()
// (detect/seam_metrics.hpp). Per keyframe (seam_frame_*): precision = matched detections /
// detections over all frames (a frame with no joint in view still counts its detections), recall =
// matched seams / seams in view; endpoint error over the ends seen on both sides; time = thread CPU
// of detect(). Fused (seam_precision=, seam_recall=, seam_endpoint_mm=, the figures): every
// detection of the sequence goes to a SeamFusion (detect/seam_fusion.hpp); its fused seams are
// matched to the seams seen in at least one frame, a true end known when some frame saw it (supporting
// detections, Detection::support_only, go to the fusion only: they are not claims of a keyframe). The recall
// of each kind (seam_recall_fillet=, seam_recall_butt=) is printed beside the recall over all seams.
// For a reader, each fused seam that matches no true one and each true seam seen but not found (with
// the keyframes that saw and matched it) is printed in the world frame. --area-sampling renders the
// colour integrated over each pixel (sim::RenderOptions::area_sampling: five rays a pixel) instead of
// at its centre; --shadows and --ambient-occlusion RAYS light it with the light's shadows and
// ambient occlusion (sim::RenderOptions); detect_area_sampling=, detect_shadows= and
// detect_ambient_occlusion_rays= say what the command line asked for (the presets have all off).

#include "bench_command.hpp"

#if HWR_WITH_SIM
#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <sstream>
#include <string>
#include <vector>

#include "bench_sequences.hpp"
#include "thread_clock.hpp"
#include "hwr/detect/geometric_seam_detector.hpp"
#include "hwr/detect/seam_fusion.hpp"
#include "hwr/detect/seam_metrics.hpp"
#include "hwr/recon/plate_fit.hpp"

namespace hwr::bench {

namespace {

double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

double percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, static_cast<size_t>(q * static_cast<double>(v.size() - 1) + 0.5))];
}

// The truth's seams as segments; a fillet's open side is the horizontal direction from its seam
// towards its base plate's centre (the plate whose name ends in "/base").
std::vector<detect::SeamSegment> truth_seams(const recon::WeldGroundTruth& gt) {
  std::vector<detect::SeamSegment> out;
  for (const recon::SeamTruth& s : gt.seams) {
    detect::SeamSegment seg;
    seg.a = s.start_world;
    seg.b = s.end_world;
    seg.kind = s.type == recon::SeamType::kFillet ? detect::SeamKind::kFillet : detect::SeamKind::kButt;
    if (seg.kind == detect::SeamKind::kFillet) {
      for (const recon::PlateTruth& p : gt.plates) {
        const bool base = p.name.size() >= 5 && p.name.compare(p.name.size() - 5, 5, "/base") == 0;
        if (!base || (p.name != s.plates[0] && p.name != s.plates[1])) continue;
        const Eigen::Vector3d u = (s.end_world - s.start_world).normalized();
        Eigen::Vector3d side = p.T_world_plate.translation() - s.start_world;
        side -= side.dot(u) * u;
        side.z() = 0.0;
        if (side.norm() > 1e-6) seg.open_side = side.normalized();
      }
    }
    out.push_back(seg);
  }
  return out;
}

struct Tally {
  int frames = 0, frames_with_seams = 0, detections = 0, matched = 0;
  int truths[2] = {0, 0}, truths_matched[2] = {0, 0};  // per SeamKind
  std::vector<double> endpoint_mm, lateral_mm, detect_ms;
  // Fused over the sequence (SeamFusion): fused seams, those matched, the seams seen at least once.
  int fused = 0, fused_matched = 0;
  int seen[2] = {0, 0}, seen_matched[2] = {0, 0};
  std::vector<double> fused_endpoint_mm, fused_lateral_mm;
};

int run_detect(int argc, char** argv) {
  std::string sequences = "lab,outdoor";
  int step = 10;
  double duration_s = 0.0, max_range_m = 3.5;  // the detector's depth limit (OrganizedCloudConfig)
  SimRendering rendering;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&](const char* what) -> std::string {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "hwr-bench detect: %s needs a value\n", what);
        std::exit(2);
      }
      return argv[++i];
    };
    if (a == "--sequences") {
      sequences = value("--sequences");
    } else if (a == "--step") {
      step = std::atoi(value("--step").c_str());
      if (step < 1) {
        std::fprintf(stderr, "hwr-bench detect: --step must be >= 1\n");
        return 2;
      }
    } else if (a == "--duration") {
      duration_s = std::atof(value("--duration").c_str());
    } else if (a == "--max-range") {
      max_range_m = std::atof(value("--max-range").c_str());
    } else if (a == "--area-sampling") {
      rendering.area_sampling = true;
    } else if (a == "--shadows") {
      rendering.shadows = true;
    } else if (a == "--ambient-occlusion") {
      rendering.ambient_occlusion_rays = std::atoi(value("--ambient-occlusion").c_str());
      if (rendering.ambient_occlusion_rays < 1 || rendering.ambient_occlusion_rays > 64) {
        std::fprintf(stderr, "hwr-bench detect: --ambient-occlusion takes 1-64 rays\n");
        return 2;
      }
    } else {
      std::fprintf(
          stderr,
          "usage: hwr-bench detect [--sequences lab,outdoor] [--step N] [--duration S] [--max-range M] "
          "[--area-sampling] [--shadows] [--ambient-occlusion RAYS]\n");
      return a == "--help" || a == "-h" ? 0 : 2;
    }
  }
  std::vector<std::string> names;
  std::stringstream ss(sequences);
  for (std::string n; std::getline(ss, n, ',');)
    if (!n.empty()) names.push_back(n);

  const detect::GeometricSeamConfig config;
  std::printf(
      "hwr-bench detect: the geometric seam detector per keyframe (every %d-th frame, true poses), seams in "
      "view "
      "within %.1f m; match: %.0f deg, %.0f mm, %.0f %% overlap; colour %s, %s, ambient occlusion %d "
      "rays\n",
      step, max_range_m, detect::SeamMatchConfig{}.max_angle_rad * 57.29577951308232,
      detect::SeamMatchConfig{}.max_lateral_m * 1e3, detect::SeamMatchConfig{}.min_overlap * 100,
      rendering.area_sampling ? "integrated over each pixel (5 rays)" : "at each pixel's centre",
      rendering.shadows ? "with the light's shadows" : "no shadows", rendering.ambient_occlusion_rays);
  std::printf("%-10s %7s %9s %7s %9s %9s %9s %13s %13s %11s\n", "sequence", "frames", "w/ seams", "dets",
              "precision", "recall", "fillets", "endpoint mm", "lateral mm", "detect ms");
  Tally all;
  std::vector<std::string> keys;
  auto report = [&](const std::string& label, const Tally& x) {
    const int truths_all = x.truths[0] + x.truths[1];
    const double precision = x.detections > 0 ? static_cast<double>(x.matched) / x.detections : 1.0;
    const double recall =
        truths_all > 0 ? static_cast<double>(x.truths_matched[0] + x.truths_matched[1]) / truths_all : 0.0;
    const double recall_fillet =
        x.truths[0] > 0 ? static_cast<double>(x.truths_matched[0]) / x.truths[0] : 0.0;
    const double recall_butt = x.truths[1] > 0 ? static_cast<double>(x.truths_matched[1]) / x.truths[1] : 0.0;
    std::printf("%-10s %7d %9d %7d %9.3f %9.3f %9.3f %6.1f / %-5.1f %6.1f / %-5.1f %5.2f / %-5.2f\n",
                label.c_str(), x.frames, x.frames_with_seams, x.detections, precision, recall, recall_fillet,
                median(x.endpoint_mm), percentile(x.endpoint_mm, 0.9), median(x.lateral_mm),
                percentile(x.lateral_mm, 0.9), median(x.detect_ms), percentile(x.detect_ms, 0.95));
    std::printf("%-10s seams in view: %d fillet (%d matched), %d butt (%d matched); ends compared %zu\n", "",
                x.truths[0], x.truths_matched[0], x.truths[1], x.truths_matched[1], x.endpoint_mm.size());
    const int seen_all = x.seen[0] + x.seen[1];
    const double fused_precision = x.fused > 0 ? static_cast<double>(x.fused_matched) / x.fused : 1.0;
    const double fused_recall =
        seen_all > 0 ? static_cast<double>(x.seen_matched[0] + x.seen_matched[1]) / seen_all : 0.0;
    const double fused_recall_fillet =
        x.seen[0] > 0 ? static_cast<double>(x.seen_matched[0]) / x.seen[0] : 0.0;
    const double fused_recall_butt = x.seen[1] > 0 ? static_cast<double>(x.seen_matched[1]) / x.seen[1] : 0.0;
    std::printf(
        "%-10s fused over the keyframes: %d seams, %d matched (precision %.3f); seams seen: %d fillet (%d "
        "matched), %d butt (%d matched), recall %.3f (fillets %.3f); endpoint %.1f mm median (%zu ends), "
        "lateral %.1f mm\n",
        "", x.fused, x.fused_matched, fused_precision, x.seen[0], x.seen_matched[0], x.seen[1],
        x.seen_matched[1], fused_recall, fused_recall_fillet, median(x.fused_endpoint_mm),
        x.fused_endpoint_mm.size(), median(x.fused_lateral_mm));
    char buf[1024];
    const std::string p = label == "all" ? "" : label + "_";
    std::snprintf(
        buf, sizeof(buf),
        "seam_%sprecision=%.3f\nseam_%srecall=%.3f\nseam_%srecall_fillet=%.3f\nseam_%srecall_butt=%.3f\n"
        "seam_%sendpoint_mm=%.2f\nseam_%slateral_mm=%.2f\nseam_%sframe_precision=%.3f\n"
        "seam_%sframe_recall=%.3f\nseam_%sframe_recall_fillet=%.3f\nseam_%sframe_recall_butt=%.3f\n"
        "seam_%sframe_endpoint_mm=%.2f\nseam_%sframe_lateral_mm=%.2f\ndetect_%sms_median=%.3f\n"
        "detect_%sms_p95=%.3f",
        p.c_str(), fused_precision, p.c_str(), fused_recall, p.c_str(), fused_recall_fillet, p.c_str(),
        fused_recall_butt, p.c_str(), median(x.fused_endpoint_mm), p.c_str(), median(x.fused_lateral_mm),
        p.c_str(), precision, p.c_str(), recall, p.c_str(), recall_fillet, p.c_str(), recall_butt, p.c_str(),
        median(x.endpoint_mm), p.c_str(), median(x.lateral_mm), p.c_str(), median(x.detect_ms), p.c_str(),
        percentile(x.detect_ms, 0.95));
    keys.push_back(buf);
  };
  for (const std::string& name : names) {
    auto seq = open_sequence(name, duration_s, rendering);
    if (!seq.ok()) {
      std::fprintf(stderr, "hwr-bench detect: %s: %s\n", name.c_str(), seq.status().message().c_str());
      return 1;
    }
    auto gt = recon::parse_weld_groundtruth(seq->weld_truth_yaml, name + " weld truth");
    if (!gt.ok()) {
      std::fprintf(stderr, "hwr-bench detect: %s\n", gt.status().message().c_str());
      return 1;
    }
    const std::vector<detect::SeamSegment> truths = truth_seams(gt.value());
    const hal::PinholeIntrinsics& K = seq->log.info.intrinsics;
    auto detector = detect::GeometricSeamDetector::create(config, K);
    if (!detector.ok()) {
      std::fprintf(stderr, "hwr-bench detect: %s\n", detector.status().message().c_str());
      return 2;
    }
    if (seq->groundtruth.size() != seq->log.frame_t_ns.size()) {
      std::fprintf(stderr, "hwr-bench detect: %s: %zu truth poses for %zu frames\n", name.c_str(),
                   seq->groundtruth.size(), seq->log.frame_t_ns.size());
      return 1;
    }
    Tally t;
    hal::RgbdFrame frame;
    detect::DetectionList dets(config.max_detections);
    std::vector<detect::SeamSegment> visible, found;
    detect::SeamFusion fusion;
    // Per true seam: seen in some frame, and each end seen.
    std::vector<detect::SeamSegment> seen_truths = truths;
    std::vector<char> seen(truths.size(), 0);
    // Per true seam: keyframes that see it, and those where a detection matches it.
    std::vector<int> frames_in_view(truths.size(), 0), frames_matched(truths.size(), 0);
    std::vector<size_t> visible_truth;
    for (detect::SeamSegment& st : seen_truths) st.end_known = {false, false};
    for (size_t i = 0; i < seq->log.frame_t_ns.size(); i += static_cast<size_t>(step)) {
      const core::Status loaded = seq->log.load_frame(i, &frame);
      if (!loaded.ok()) {
        std::fprintf(stderr, "hwr-bench detect: %s frame %zu: %s\n", name.c_str(), i,
                     loaded.message().c_str());
        return 1;
      }
      const Eigen::Isometry3d& T_world_cam = seq->groundtruth[i].T_world_body;
      detect::KeyframeView view;
      view.keyframe_id = static_cast<int32_t>(i);
      view.t_ns = frame.t_ns;
      view.K = K;
      view.bgr = &frame.bgr;
      view.depth_m = &frame.depth_m;
      view.T_world_cam = T_world_cam;
      const double t0 = thread_cpu_s();
      const core::Status s = (*detector)->detect(view, &dets);
      t.detect_ms.push_back(1e3 * (thread_cpu_s() - t0));
      if (!s.ok()) {
        std::fprintf(stderr, "hwr-bench detect: %s frame %zu: %s\n", name.c_str(), i, s.message().c_str());
        return 1;
      }
      visible.clear();
      visible_truth.clear();
      for (size_t k = 0; k < truths.size(); ++k) {
        detect::SeamSegment part;
        if (!detect::visible_seam_part(truths[k], T_world_cam, K, frame.depth_m, config.noise,
                                       config.cloud.min_depth_m, max_range_m, 0.1, &part))
          continue;
        visible.push_back(part);
        visible_truth.push_back(k);
        ++frames_in_view[k];
        seen[k] = 1;
        for (int e = 0; e < 2; ++e)
          seen_truths[k].end_known[e] = seen_truths[k].end_known[e] || part.end_known[e];
      }
      for (int k = 0; k < dets.size(); ++k) fusion.add(dets[k]);
      found.clear();
      for (int k = 0; k < dets.size(); ++k)
        if (!dets[k].support_only) found.push_back(detect::seam_of(dets[k]));  // supporting: fusion only
      const detect::SeamScore score = detect::score_seams(found, visible);
      ++t.frames;
      t.frames_with_seams += visible.empty() ? 0 : 1;
      t.detections += score.detections;
      t.matched += score.matched;
      for (const detect::SeamSegment& v : visible) ++t.truths[static_cast<int>(v.kind)];
      for (const detect::SeamMatch& m : score.matches) {
        ++frames_matched[visible_truth[static_cast<size_t>(m.truth)]];
        ++t.truths_matched[static_cast<int>(visible[static_cast<size_t>(m.truth)].kind)];
        t.lateral_mm.push_back(1e3 * m.lateral_m);
        for (int e = 0; e < 2; ++e)
          if (m.endpoint_valid[e]) t.endpoint_mm.push_back(1e3 * m.endpoint_m[e]);
      }
    }
    {
      std::vector<detect::SeamSegment> fused_seams, seen_list;
      const std::vector<detect::FusedSeam> fused_all = fusion.fused();
      for (const detect::FusedSeam& f : fused_all) fused_seams.push_back(f.seam);
      std::vector<size_t> seen_index;
      for (size_t k = 0; k < truths.size(); ++k) {
        if (!seen[k]) continue;
        seen_list.push_back(seen_truths[k]);
        seen_index.push_back(k);
      }
      const detect::SeamScore fs = detect::score_seams(fused_seams, seen_list);
      // The true seams seen but not found once fused, with how often a keyframe found them.
      std::vector<bool> truth_found(seen_list.size(), false);
      for (const detect::SeamMatch& m : fs.matches) truth_found[static_cast<size_t>(m.truth)] = true;
      for (size_t j = 0; j < seen_list.size(); ++j) {
        if (truth_found[j]) continue;
        const size_t k = seen_index[j];
        const detect::SeamSegment& v = truths[k];
        std::printf(
            "%s: true %s seam not found: (%.3f, %.3f, %.3f) -> (%.3f, %.3f, %.3f) m, matched in %d of the %d "
            "keyframes that see it\n",
            name.c_str(), detect::seam_kind_name(v.kind), v.a.x(), v.a.y(), v.a.z(), v.b.x(), v.b.y(),
            v.b.z(), frames_matched[k], frames_in_view[k]);
      }
      t.fused = fs.detections;
      t.fused_matched = fs.matched;
      for (const detect::SeamSegment& v : seen_list) ++t.seen[static_cast<int>(v.kind)];
      // The fused seams that match no true one, for a reader to look at (world frame).
      std::vector<bool> fused_matched(fused_seams.size(), false);
      for (const detect::SeamMatch& m : fs.matches) fused_matched[static_cast<size_t>(m.detected)] = true;
      for (size_t k = 0; k < fused_seams.size(); ++k) {
        if (fused_matched[k]) continue;
        const detect::SeamSegment& f = fused_seams[k];
        std::printf(
            "%s: fused %s seam matching no true seam: (%.3f, %.3f, %.3f) -> (%.3f, %.3f, %.3f) m, from %d "
            "detections\n",
            name.c_str(), detect::seam_kind_name(f.kind), f.a.x(), f.a.y(), f.a.z(), f.b.x(), f.b.y(),
            f.b.z(), fused_all[k].detections);
      }
      for (const detect::SeamMatch& m : fs.matches) {
        ++t.seen_matched[static_cast<int>(seen_list[static_cast<size_t>(m.truth)].kind)];
        t.fused_lateral_mm.push_back(1e3 * m.lateral_m);
        for (int e = 0; e < 2; ++e)
          if (m.endpoint_valid[e]) t.fused_endpoint_mm.push_back(1e3 * m.endpoint_m[e]);
      }
    }
    report(name, t);
    all.frames += t.frames;
    all.frames_with_seams += t.frames_with_seams;
    all.detections += t.detections;
    all.matched += t.matched;
    for (int k = 0; k < 2; ++k) {
      all.truths[k] += t.truths[k];
      all.truths_matched[k] += t.truths_matched[k];
    }
    all.endpoint_mm.insert(all.endpoint_mm.end(), t.endpoint_mm.begin(), t.endpoint_mm.end());
    all.lateral_mm.insert(all.lateral_mm.end(), t.lateral_mm.begin(), t.lateral_mm.end());
    all.detect_ms.insert(all.detect_ms.end(), t.detect_ms.begin(), t.detect_ms.end());
    all.fused += t.fused;
    all.fused_matched += t.fused_matched;
    for (int k = 0; k < 2; ++k) {
      all.seen[k] += t.seen[k];
      all.seen_matched[k] += t.seen_matched[k];
    }
    all.fused_endpoint_mm.insert(all.fused_endpoint_mm.end(), t.fused_endpoint_mm.begin(),
                                 t.fused_endpoint_mm.end());
    all.fused_lateral_mm.insert(all.fused_lateral_mm.end(), t.fused_lateral_mm.begin(),
                                t.fused_lateral_mm.end());
  }
  report("all", all);
  std::printf("detect_area_sampling=%d\ndetect_shadows=%d\ndetect_ambient_occlusion_rays=%d\n",
              rendering.area_sampling ? 1 : 0, rendering.shadows ? 1 : 0, rendering.ambient_occlusion_rays);
  for (const std::string& k : keys) std::printf("%s\n", k.c_str());
  return 0;
}

}  // namespace

HWR_BENCH_COMMAND(
    detect, "detect",
    "welding seams (issue #7): the geometric detector against the sim's seams, per keyframe and fused, "
    "precision, recall, endpoint error, time [--sequences lab,outdoor] [--step N] [--duration S] "
    "[--max-range M]",
    run_detect);

}  // namespace hwr::bench

#endif  // HWR_WITH_SIM
