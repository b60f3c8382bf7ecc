#include "hwr/recon/relocalization_confirmation.hpp"

namespace hwr::recon {

const char* confirmation_verdict_name(ConfirmationVerdict v) {
  switch (v) {
    case ConfirmationVerdict::kNotLocalized:
      return "not localized";
    case ConfirmationVerdict::kPending:
      return "pending confirmation";
    case ConfirmationVerdict::kAccepted:
      return "accepted";
  }
  return "?";
}

RelocalizationConfirmation::RelocalizationConfirmation(const RelocalizationConfirmationConfig& config)
    : config_(config) {}

void RelocalizationConfirmation::reset() {
  accepted_ = pending_ = false;
  accepted_T_ = pending_T_ = Eigen::Isometry3d::Identity();
  pending_support_ = 0;
  pending_p_world_cam_.setZero();
  superseded_ = 0;
}

int RelocalizationConfirmation::support(const RelocalizationResult& result) {
  if (result.orb_refined) return 2;
  return result.polish_refused ? 0 : 1;
}

bool RelocalizationConfirmation::agree(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b,
                                       const Eigen::Isometry3d& T_world_cam) const {
  const double d_m = ((a * T_world_cam).translation() - (b * T_world_cam).translation()).norm();
  const double d_rad = Eigen::AngleAxisd(a.linear().transpose() * b.linear()).angle();
  return d_m <= config_.agree_m && d_rad <= config_.agree_rad;
}

ConfirmationVerdict RelocalizationConfirmation::offer(const RelocalizationResult& result,
                                                      const RelocalizationQuery& query) {
  if (accepted_) return ConfirmationVerdict::kAccepted;
  if (!result.localized) return pending_ ? ConfirmationVerdict::kPending : ConfirmationVerdict::kNotLocalized;
  const int result_support = support(result);
  const bool needs_confirmation =
      (config_.confirm_weak_without_position && result.orb_refined_weak && !query.position.valid) ||
      (config_.confirm_unpolished && result_support == 0);
  const bool agrees = pending_ && agree(pending_T_, result.T_prior_world, query.T_world_cam);
  // Agreement from (nearly) the same place is the same evidence again (header): outdoor f4708 (seed 4)
  // held a weak fit 49 m off at 8.29 m of motion, and the attempt at 9.01 m, 0.7 m on, repeated it.
  const bool separated =
      (query.T_world_cam.translation() - pending_p_world_cam_).norm() >= config_.min_separation_m;
  const bool confirms = agrees && separated;
  if (agrees && !separated && needs_confirmation) return ConfirmationVerdict::kPending;
  if (confirms || !needs_confirmation) {
    accepted_ = true;
    // Of two that agree, the better supported (header): outdoor f4609 (seed 2) held a weak ORB fit
    // 0.20 cm from the truth, and the later fit that confirmed it was an unpolished NDT one 4.5 cm off.
    accepted_T_ = confirms && pending_support_ > result_support ? pending_T_ : result.T_prior_world;
    pending_ = false;
    return ConfirmationVerdict::kAccepted;
  }
  if (pending_) ++superseded_;
  pending_ = true;
  pending_T_ = result.T_prior_world;
  pending_p_world_cam_ = query.T_world_cam.translation();
  pending_support_ = result_support;
  return ConfirmationVerdict::kPending;
}

}  // namespace hwr::recon
