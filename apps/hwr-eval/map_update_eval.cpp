// hwr-eval map-update: what a prior-map update (hwr-robot --prior-map P --map-out D) deleted, against
// the simulator's ground truth of the plates (issue #6 acceptance: a moved plate disappears from its
// old place; static geometry is not eroded, point loss <= 1 %).
//
// Every prior segment that D holds a new version of (same id, below relocalization.yaml's
// first_segment_id) is compared with P's: points within --radius of a --moved plate's old place
// (the plate boxes of P's run, the prior frame, inflated by --margin) are "old place"; the rest are
// "elsewhere" (static geometry, and any clutter removed between the runs: an upper bound of the
// static loss). A plate that moved by less than its size still covers part of its old place, so the
// old place is never wholly free: 100 % is not expected. Prints a readable block and key=value lines.
//
// The boxes are the truth's, the prior's points its first run's estimate: the prior drifts (in the
// lab revisit its bench top at the moved plate lies 3 cm below the truth's), and a box of the truth
// as given then holds the bench under the plate and misses its top. With --truth-traj (the first
// run's groundtruth.txt) each box is placed in each segment as its keyframes saw it
// (recon/region_ae.hpp does the same for AE): through the segment's keyframe whose look-at point
// (kLookAheadM along its optical axis) is nearest the plate's centre,
//   T_prior_box = T_prior_cam_est(t) * T_world_cam_true(t)^-1 * T_world_plate_true,
// the map's local error at that place kept, its drift not.
#include "map_update_eval.hpp"

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <limits>
#include <string>
#include <vector>

#include "hwr/core/tum_trajectory.hpp"
#include "hwr/recon/map_store.hpp"
#include "hwr/recon/plate_fit.hpp"
#include "hwr/recon/truth_weld_regions.hpp"

namespace hwr_eval {

namespace {

constexpr double kLookAheadM = 1.5;             // a keyframe's look-at point along its optical axis
constexpr int64_t kMaxTruthGapNs = 50'000'000;  // truth samples further apart are not interpolated

int usage_map_update(const char* msg) {
  if (msg != nullptr) std::fprintf(stderr, "hwr-eval map-update: %s\n", msg);
  std::fprintf(
      stderr,
      "usage: hwr-eval map-update --prior P --updated D --groundtruth WELD_YAML --moved NAME[,NAME...]\n"
      "                           [--margin M] [--truth-traj GT]\n"
      "  P: the first run's map store; D: the second run's (--map-out of hwr-robot --prior-map P);\n"
      "  WELD_YAML: the first run's weld_groundtruth.yaml; NAME: a joint whose plates moved\n"
      "  (its plates are NAME/...); M: inflation of the plate boxes (default 0.03 m);\n"
      "  GT: the first run's groundtruth.txt: each box placed in each segment through the keyframe that\n"
      "  looked nearest it (the prior's drift removed); without it the boxes are used as given\n");
  return 2;
}

}  // namespace

int run_map_update(int argc, char** argv) {
  std::string prior_dir, updated_dir, gt_path, moved_list, truth_traj_path;
  double margin_m = 0.03;
  for (int i = 2; i < argc; ++i) {
    const std::string a = argv[i];
    if (i + 1 >= argc) return usage_map_update(("missing value after " + a).c_str());
    const char* v = argv[++i];
    if (a == "--prior") {
      prior_dir = v;
    } else if (a == "--updated") {
      updated_dir = v;
    } else if (a == "--groundtruth") {
      gt_path = v;
    } else if (a == "--moved") {
      moved_list = v;
    } else if (a == "--truth-traj") {
      truth_traj_path = v;
    } else if (a == "--margin") {
      char* end = nullptr;
      margin_m = std::strtod(v, &end);
      if (*end != '\0' || !(margin_m >= 0 && margin_m < 1))
        return usage_map_update("--margin: metres in [0, 1)");
    } else {
      return usage_map_update(("unknown option " + a).c_str());
    }
  }
  if (prior_dir.empty() || updated_dir.empty() || gt_path.empty() || moved_list.empty()) {
    return usage_map_update("--prior, --updated, --groundtruth and --moved are required");
  }
  auto gt = hwr::recon::read_weld_groundtruth(gt_path);
  if (!gt.ok()) {
    std::fprintf(stderr, "hwr-eval: %s\n", gt.status().message().c_str());
    return 1;
  }
  std::vector<hwr::recon::OrientedBox> old_place;
  std::vector<std::string> old_place_names;  // the plate of each box
  size_t start = 0;
  while (start <= moved_list.size()) {
    const size_t comma = moved_list.find(',', start);
    const std::string name =
        moved_list.substr(start, comma == std::string::npos ? std::string::npos : comma - start);
    size_t found = 0;
    for (const auto& p : gt->plates) {
      if (p.name.rfind(name + "/", 0) != 0) continue;
      hwr::recon::OrientedBox b;
      b.T_world_box = p.T_world_plate;
      b.half_size_m = p.size_m / 2 + Eigen::Vector3d::Constant(margin_m);
      old_place.push_back(b);
      old_place_names.push_back(p.name);
      ++found;
    }
    if (found == 0) {
      std::fprintf(stderr, "hwr-eval: --moved: no plate of %s in %s\n", name.c_str(), gt_path.c_str());
      return 1;
    }
    if (comma == std::string::npos) break;
    start = comma + 1;
  }
  std::vector<hwr::core::StampedPose> truth;
  if (!truth_traj_path.empty()) {
    auto t = hwr::core::read_tum_trajectory(truth_traj_path);
    if (!t.ok()) {
      std::fprintf(stderr, "hwr-eval: %s\n", t.status().message().c_str());
      return 1;
    }
    truth = std::move(t.value());
  }
  auto prior = hwr::recon::MapStore::open_existing(prior_dir);
  auto updated = hwr::recon::MapStore::open_existing(updated_dir);
  if (!prior.ok() || !updated.ok()) {
    std::fprintf(stderr, "hwr-eval: %s\n",
                 (!prior.ok() ? prior.status() : updated.status()).message().c_str());
    return 1;
  }
  auto prior_list = prior->list_segments();
  auto updated_list = updated->list_segments();
  if (!prior_list.ok() || !updated_list.ok()) {
    std::fprintf(stderr, "hwr-eval: %s\n",
                 (!prior_list.ok() ? prior_list.status() : updated_list.status()).message().c_str());
    return 1;
  }
  int64_t old_before = 0, old_after = 0, else_before = 0, else_after = 0, old_all = 0;
  // Per plate (a point in two plates' boxes, where a web stands on its base, counts for both): prior
  // points in every segment, and before / after in the updated ones.
  const size_t n_plates = old_place.size();
  std::vector<int64_t> plate_all(n_plates, 0), plate_before(n_plates, 0), plate_after(n_plates, 0);
  int segments_compared = 0;
  // The boxes in a segment's frame of the prior (header): placed through its keyframe nearest each
  // plate with --truth-traj, else as given. Fails when no keyframe of the segment has a truth pose.
  std::vector<hwr::recon::OrientedBox> boxes(n_plates);
  auto place_boxes = [&](const hwr::recon::SegmentRecord& s) -> bool {
    for (size_t k = 0; k < n_plates; ++k) {
      boxes[k] = old_place[k];
      if (truth.empty()) continue;
      const Eigen::Vector3d centre_true = old_place[k].T_world_box.translation();
      double best = std::numeric_limits<double>::infinity();
      bool placed = false;
      for (const auto& kf : s.keyframes) {
        Eigen::Isometry3d T_world_cam_true;
        if (!hwr::recon::truth_pose_at(truth, kf.t_ns, kMaxTruthGapNs, &T_world_cam_true)) continue;
        // Nearness in the truth's frame: the keyframe's true look-at point to the true plate.
        const double d = (T_world_cam_true * Eigen::Vector3d(0, 0, kLookAheadM) - centre_true).norm();
        if (d >= best) continue;
        best = d;
        boxes[k].T_world_box = kf.T_world_cam * T_world_cam_true.inverse() * old_place[k].T_world_box;
        placed = true;
      }
      if (!placed) return false;
    }
    return true;
  };
  auto count = [&](const hwr::recon::SegmentRecord& s, int64_t* in_old, int64_t* elsewhere,
                   std::vector<int64_t>* per_plate) {
    for (const auto& p : s.points_segment) {
      const Eigen::Vector3d w = s.T_world_segment * Eigen::Vector3d(p.x_m, p.y_m, p.z_m);
      bool old = false;
      for (size_t k = 0; k < n_plates; ++k) {
        if (boxes[k].distance_m(w) != 0.0) continue;
        old = true;
        ++(*per_plate)[k];
      }
      ++*(old ? in_old : elsewhere);
    }
  };
  std::vector<int64_t> seg_plate(n_plates), seg_plate_after(n_plates);
  for (const auto& ps : prior_list.value()) {
    auto a = prior->read_segment(ps.segment_id);
    if (!a.ok()) {
      std::fprintf(stderr, "hwr-eval: %s\n", a.status().message().c_str());
      return 1;
    }
    bool has_update = false;
    for (const auto& us : updated_list.value()) has_update = has_update || us.segment_id == ps.segment_id;
    if (!place_boxes(a.value())) {
      std::fprintf(stderr, "hwr-eval: --truth-traj %s has no pose at any keyframe of prior segment %u\n",
                   truth_traj_path.c_str(), ps.segment_id);
      return 1;
    }
    int64_t o = 0, e = 0;
    std::fill(seg_plate.begin(), seg_plate.end(), 0);
    count(a.value(), &o, &e, &seg_plate);
    old_all += o;
    for (size_t k = 0; k < n_plates; ++k) plate_all[k] += seg_plate[k];
    if (!has_update) {
      if (o > 0)
        std::printf("  segment %u: %lld old-place points, not updated\n", ps.segment_id,
                    static_cast<long long>(o));
      continue;
    }
    auto b = updated->read_segment(ps.segment_id);
    if (!b.ok()) {
      std::fprintf(stderr, "hwr-eval: %s\n", b.status().message().c_str());
      return 1;
    }
    old_before += o;
    else_before += e;
    int64_t o_after = 0, e_after = 0;
    std::fill(seg_plate_after.begin(), seg_plate_after.end(), 0);
    count(b.value(), &o_after, &e_after, &seg_plate_after);
    for (size_t k = 0; k < n_plates; ++k) {
      plate_before[k] += seg_plate[k];
      plate_after[k] += seg_plate_after[k];
    }
    old_after += o_after;
    else_after += e_after;
    std::printf("  segment %u: %lld old-place points, %lld deleted; elsewhere %lld of %lld deleted\n",
                ps.segment_id, static_cast<long long>(o), static_cast<long long>(o - o_after),
                static_cast<long long>(e - e_after), static_cast<long long>(e));
    ++segments_compared;
  }
  const double old_deleted_pct =
      old_all > 0 ? 100.0 * (old_all - (old_all - old_before + old_after)) / old_all : 0;
  const double static_loss_pct = else_before > 0 ? 100.0 * (else_before - else_after) / else_before : 0;
  std::printf("map update: %d prior segments updated of %zu\n", segments_compared, prior_list->size());
  std::printf("  old place of the moved plates: %lld prior points, %lld deleted (%.1f %%)\n",
              static_cast<long long>(old_all), static_cast<long long>(old_before - old_after),
              old_deleted_pct);
  std::printf(
      "  elsewhere in the updated segments: %lld of %lld points deleted (%.3f %%; static geometry and any "
      "removed clutter)\n",
      static_cast<long long>(else_before - else_after), static_cast<long long>(else_before), static_loss_pct);
  std::vector<double> plate_pct(n_plates, 0);
  for (size_t k = 0; k < n_plates; ++k) {
    plate_pct[k] = plate_all[k] > 0 ? 100.0 * (plate_before[k] - plate_after[k]) / plate_all[k] : 0;
    std::printf("  plate %s: %lld prior points, %lld deleted (%.1f %%)\n", old_place_names[k].c_str(),
                static_cast<long long>(plate_all[k]),
                static_cast<long long>(plate_before[k] - plate_after[k]), plate_pct[k]);
  }
  std::printf(
      "map_update_segments=%d\nmoved_old_place_points=%lld\nmoved_old_place_deleted_pct=%.2f\n"
      "elsewhere_deleted_pct=%.4f\n",
      segments_compared, static_cast<long long>(old_all), old_deleted_pct, static_loss_pct);
  for (size_t k = 0; k < n_plates; ++k) {
    std::string key = old_place_names[k];
    for (char& ch : key) ch = (ch == '/' || ch == ' ') ? '_' : ch;
    std::printf("moved_plate_deleted_pct_%s=%.2f\n", key.c_str(), plate_pct[k]);
  }
  return 0;
}

}  // namespace hwr_eval
