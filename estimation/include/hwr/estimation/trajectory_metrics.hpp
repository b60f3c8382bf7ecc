#pragma once
// Trajectory accuracy as the TUM RGB-D benchmark measures it (Sturm et al., IROS 2012, Sec. VI):
//  - association of estimate and ground-truth poses by timestamp (associate.py),
//  - absolute trajectory error (ATE, evaluate_ate.py): the estimate is aligned to the ground truth
//    by the least-squares rigid (or similarity) transform of Umeyama (PAMI 1991), computed with
//    Eigen::umeyama, then e_i = ||p_gt,i - S·p_est,i||,
//  - relative pose error (RPE, evaluate_rpe.py --fixed_delta): for estimate pairs (i, j) a fixed
//    delta apart, E_ij = (P_i^-1 P_j) · (Q_i^-1 Q_j)^-1 with P estimate and Q ground truth (the
//    script's ominus(ominus(P_j, P_i), ominus(Q_j, Q_i))); errors are |trans(E_ij)| and angle(E_ij).
// Poses are T_world_body; the two trajectories may use different world frames (ATE aligns them;
// RPE does not need to).

#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "hwr/core/status.hpp"
#include "hwr/core/tum_trajectory.hpp"

namespace hwr::estimation {

// Summary of a set of non-negative errors. std is the population standard deviation (numpy's
// default, as the TUM scripts print it).
struct ErrorStats {
  size_t count = 0;
  double rmse = 0;
  double mean = 0;
  double median = 0;
  double std = 0;
  double min = 0;
  double max = 0;
};

ErrorStats compute_error_stats(const std::vector<double>& errors);

struct PoseMatch {
  size_t gt = 0;   // index into the ground truth
  size_t est = 0;  // index into the estimate
};

// associate.py: candidates (i, j) with |t_gt,i - (t_est,j + offset)| < max_dt; taken greedily by
// increasing difference (ties: lower gt index, then lower est index), each pose at most once.
// Result sorted by ground-truth index. Both inputs must be sorted by time.
std::vector<PoseMatch> associate_by_time(const std::vector<core::StampedPose>& gt,
                                         const std::vector<core::StampedPose>& est, double max_dt_s,
                                         double offset_s = 0.0);

struct AteOptions {
  double max_dt_s = 0.02;  // association window (associate.py --max_difference)
  double offset_s = 0.0;   // added to estimate timestamps before association
  bool sim3 = false;       // also estimate a scale (monocular estimates)
};

struct AteResult {
  size_t pairs = 0;  // associated poses used for alignment and errors
  // Alignment applied to the estimate: p_gt ≈ scale · R · p_est + t. T_gt_est holds R and t;
  // scale is 1 unless AteOptions::sim3.
  Eigen::Isometry3d T_gt_est = Eigen::Isometry3d::Identity();
  double scale = 1.0;
  ErrorStats translation_m;
  std::vector<PoseMatch> matches;
  std::vector<double> errors_m;  // per match, same order
};

// Fewer than 3 associated poses: error.
core::Expected<AteResult> compute_ate(const std::vector<core::StampedPose>& gt,
                                      const std::vector<core::StampedPose>& est,
                                      const AteOptions& options = {});

enum class DeltaUnit { kSeconds, kFrames };

struct RpeOptions {
  double delta = 1.0;                          // evaluate_rpe.py --delta
  DeltaUnit delta_unit = DeltaUnit::kSeconds;  // --delta_unit s | f
  double offset_s = 0.0;                       // added to estimate timestamps
};

struct RpeResult {
  size_t pairs = 0;          // relative-motion pairs evaluated
  size_t skipped_no_gt = 0;  // pairs dropped: no ground truth within 2 median gt intervals
  ErrorStats translation_m;
  ErrorStats rotation_rad;
  std::vector<std::pair<size_t, size_t>> est_pairs;  // (i, j) estimate indices, same order as errors
  std::vector<double> translation_errors_m;
  std::vector<double> rotation_errors_rad;
};

// As evaluate_rpe.py --fixed_delta without random subsampling: for every estimate pose i, j is the
// estimate index closest to index_i + delta (time in s, or frame number); pairs whose j is the last
// estimate pose are dropped, as the script does. Ground truth for each end is the pose closest in
// time, and must be within twice the median ground-truth interval. Fewer than 3 pairs: error.
core::Expected<RpeResult> compute_rpe(const std::vector<core::StampedPose>& gt,
                                      const std::vector<core::StampedPose>& est,
                                      const RpeOptions& options = {});

}  // namespace hwr::estimation
