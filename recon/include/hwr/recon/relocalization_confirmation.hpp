#pragma once
// Confirmation of a weak relocalization across attempts (issue #6: 0 false relocalizations).
//
// A weak fit (RelocalizationResult::orb_refined_weak: NDT degenerate along x, y or yaw, the pose from
// an ORB pose-only fit) stands on appearance along the weak direction, and appearance repeats. Without
// a position prior nothing bounds where it lands: in hwr-bench reloc (outdoor, seed 2, f4565, no GNSS)
// a weak fit 57 m off was accepted at 2.2 m of motion, where the place recurs along the hall; no later
// attempt (3.2-14.1 m) returned that pose, and the start localized correctly at 15.1 m.
// T_prior_world is a constant of the run (the current world frame is the run's own), so two attempts
// that are right give the same one, whatever the robot moved in between. Such a fit is therefore held
// as pending and accepted only when a later attempt of the run localizes to the same T_prior_world
// (agree_m at the later camera, agree_rad); the accepted pose is then the later one when an ORB fit
// refined it, else the pending (ORB) one. A fit that is not weak, or one found with a position prior
// (a GNSS fix bounds the repeats it can land on, position_gate in relocalizer.hpp), is accepted at once,
// as is a later result that needs no confirmation even when a pending one disagrees with it.
//
// A converged fit whose ORB polish was refused (RelocalizationResult::polish_refused: its accuracy
// rests on NDT alone) is held as well, with or without a position prior (confirm_unpolished): a GNSS
// fix bounds where a fit lands to metres, not its accuracy. In hwr-bench reloc (outdoor, seed 2, f4500,
// GNSS rows) such a fit was accepted 11.4 cm / 1.45 deg off (its polish kept 99 of the 100 inliers it
// needs); it was the only accepted fit of the 378 in that draw with a refused polish. Of two that agree,
// the kept pose is the better supported: ORB-refined, then NDT with the polish not tried, then NDT with
// the polish refused (ties: the later).
//
// The confirming attempt must see another place: its camera at least min_separation_m (current world
// frame) from the held fit's. Two attempts 0.7 m apart match the same view against the same prior
// keyframes, so a repeated place fools both alike: in hwr-bench reloc (outdoor, seed 4, f4708, no
// GNSS) a weak fit 49 m off (the container rows repeat) was held at 8.29 m of motion and confirmed by
// the same wrong pose at 9.01 m. A nearer attempt that agrees leaves the held fit (and its camera)
// waiting; one that disagrees replaces it as before.
//
// Used by RelocalizationWorker (the robot) and hwr-bench reloc, one per run; no allocation.

#include <Eigen/Geometry>

#include "hwr/recon/relocalizer.hpp"

namespace hwr::recon {

struct RelocalizationConfirmationConfig {
  bool confirm_weak_without_position = true;  // false: every localized result is accepted at once
  bool confirm_unpolished = true;             // also hold fits whose ORB polish was refused (header)
  // Two T_prior_world agree when they put the later camera within agree_m of each other and differ by
  // at most agree_rad. Correct fits are within 3 cm / 0.3 deg of the truth (hwr-bench reloc: 0.48 cm
  // at most); wrong ones metres off.
  double agree_m = 0.10;
  double agree_rad = 1.0 * 3.14159265358979323846 / 180.0;
  // A confirming attempt's camera is at least this far (current world frame) from the held fit's;
  // one nearer that agrees leaves the held fit waiting (header: the same view is the same evidence).
  double min_separation_m = 2.0;
};

enum class ConfirmationVerdict {
  kNotLocalized,  // no pose, none pending
  kPending,       // a weak pose waits for a later attempt to agree (pending_T_prior_world)
  kAccepted,      // localized: accepted_T_prior_world
};

const char* confirmation_verdict_name(ConfirmationVerdict v);

class RelocalizationConfirmation {
 public:
  explicit RelocalizationConfirmation(const RelocalizationConfirmationConfig& config = {});

  // One attempt's result and its query (the query's camera and position prior). After kAccepted the
  // run is localized; offering more results changes nothing until reset().
  ConfirmationVerdict offer(const RelocalizationResult& result, const RelocalizationQuery& query);
  // A new run (or a new prior map).
  void reset();

  bool accepted() const { return accepted_; }
  bool pending() const { return pending_; }
  const Eigen::Isometry3d& accepted_T_prior_world() const { return accepted_T_; }
  const Eigen::Isometry3d& pending_T_prior_world() const { return pending_T_; }
  // Pending poses a later one replaced (it disagreed): each was a weak fit that no attempt confirmed.
  int superseded() const { return superseded_; }
  // Whether two T_prior_world agree at the camera T_world_cam (config's agree_m, agree_rad).
  bool agree(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b,
             const Eigen::Isometry3d& T_world_cam) const;
  // How well keypoints support a localized result's pose: 2 ORB-refined, 1 NDT (polish not tried),
  // 0 NDT whose polish was refused.
  static int support(const RelocalizationResult& result);

 private:
  RelocalizationConfirmationConfig config_;
  bool accepted_ = false, pending_ = false;
  Eigen::Isometry3d accepted_T_ = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d pending_T_ = Eigen::Isometry3d::Identity();
  int pending_support_ = 0;                                        // support() of the pending result
  Eigen::Vector3d pending_p_world_cam_ = Eigen::Vector3d::Zero();  // its query's camera (world, m)
  int superseded_ = 0;
};

}  // namespace hwr::recon
