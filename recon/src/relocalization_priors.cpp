#include "hwr/recon/relocalization_priors.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>

#include "hwr/core/se3.hpp"

namespace hwr::recon {
namespace {

constexpr double kRadToDeg = 180.0 / 3.14159265358979323846;

double wrap_pi(double a) { return std::remainder(a, 2.0 * 3.14159265358979323846); }

bool positive_finite(double v) { return v > 0 && std::isfinite(v); }

std::string fmt(const char* format, double a, double b = 0, double c = 0, double d = 0) {
  char buf[160];
  std::snprintf(buf, sizeof(buf), format, a, b, c, d);
  return buf;
}

core::Status validate(const RelocalizationPriorsConfig& c) {
  if (!positive_finite(c.sigma_h_m) || !positive_finite(c.sigma_v_m)) {
    return core::InvalidArgument(
        "relocalization priors: sigma_h_m and sigma_v_m (GNSS 1-sigma) must be positive and finite, got " +
        fmt("%g and %g", c.sigma_h_m, c.sigma_v_m));
  }
  if (!c.antenna_imu_m.allFinite()) {
    return core::InvalidArgument("relocalization priors: antenna_imu_m must be finite");
  }
  if (c.gnss_capacity < 1) return core::InvalidArgument("relocalization priors: gnss_capacity must be >= 1");
  return core::Status::Ok();
}

}  // namespace

core::Expected<PriorSensorFrames> prior_sensor_frames(const PriorMap& prior,
                                                      const Eigen::Isometry3d& T_imu_cam,
                                                      const RelocalizationPriorsConfig& config) {
  HWR_RETURN_IF_ERROR(validate(config));
  const std::string rigid = core::rigid_transform_problem(T_imu_cam);
  if (!rigid.empty()) return core::InvalidArgument("relocalization priors: T_imu_cam " + rigid);
  const Eigen::Isometry3d T_cam_imu = T_imu_cam.inverse();
  PriorSensorFrames out;
  out.keyframes = static_cast<int>(prior.keyframes().size());

  // psi_prior: every tagged keyframe's sample at its IMU pose (mag_heading.hpp, place-weighted).
  estimation::MagHeadingConfig mag_config = config.mag;
  mag_config.capacity = std::max<size_t>(mag_config.capacity, prior.keyframes().size() + 2);
  estimation::MagHeadingEstimator mag(mag_config);
  std::vector<Eigen::Vector3d> p_world, p_enu;
  bool have_origin = false;
  for (const PriorKeyframe& kf : prior.keyframes()) {
    const Eigen::Isometry3d T_prior_imu = kf.T_prior_cam * T_cam_imu;
    if (kf.mag_valid) {
      ++out.keyframes_mag;
      hal::MagSample s;
      s.t_ns = kf.t_ns;
      s.field_uT = kf.mag_imu_uT;
      mag.add(s, T_prior_imu);
    }
    if (kf.gnss_valid && std::isfinite(kf.lat_deg) && std::isfinite(kf.lon_deg) && std::isfinite(kf.alt_m)) {
      ++out.keyframes_gnss;
      const core::Geodetic g{kf.lat_deg, kf.lon_deg, kf.alt_m};
      if (!have_origin) {
        out.origin = g;
        have_origin = true;
      }
      p_world.push_back(T_prior_imu * config.antenna_imu_m);
      p_enu.push_back(core::geodetic_to_enu(g, out.origin));
    }
  }
  out.mag = mag.result();
  out.mag_valid = out.mag.valid;
  if (out.keyframes_mag == 0) out.mag.reason = "no keyframe of the prior map has a magnetometer sample";

  // T_enu_prior: the track's own yaw, else (use_mag) the magnetometer's.
  if (p_world.empty()) {
    out.enu.reason = "no keyframe of the prior map has a GNSS fix";
  } else {
    const double nan = std::numeric_limits<double>::quiet_NaN();
    out.enu =
        estimation::fit_T_enu_world(p_world, p_enu, config.sigma_h_m, config.sigma_v_m, nan, config.gnss);
    if (!out.enu.valid && config.use_mag && out.mag_valid && out.enu.pairs_used >= config.gnss.min_pairs) {
      out.enu = estimation::fit_T_enu_world(p_world, p_enu, config.sigma_h_m, config.sigma_v_m,
                                            out.mag.yaw_enu_world_rad, config.gnss);
      out.enu_yaw_from_mag = out.enu.valid;
    }
  }
  out.enu_valid = out.enu.valid;
  if (out.enu_valid) {
    // Centroid of the pairs, for the yaw lever arm of a position prior far from the prior's track.
    Eigen::Vector3d c = Eigen::Vector3d::Zero();
    for (const Eigen::Vector3d& p : p_world) c += p;
    out.p_prior_antenna_centroid_m = c / static_cast<double>(p_world.size());
  }

  std::string s = "prior sensor frames: " + std::to_string(out.keyframes) + " keyframes, " +
                  std::to_string(out.keyframes_mag) + " with magnetometer, " +
                  std::to_string(out.keyframes_gnss) + " with GNSS; mag ";
  if (out.mag_valid) {
    s += fmt("psi %.2f deg sigma %.2f deg (%.0f of %.0f samples used)", out.mag.yaw_enu_world_rad * kRadToDeg,
             out.mag.sigma_rad * kRadToDeg, static_cast<double>(out.mag.used),
             static_cast<double>(out.mag.stored));
  } else {
    s += "none (" + out.mag.reason + ")";
  }
  s += "; ENU ";
  if (out.enu_valid) {
    s += fmt("psi %.2f deg sigma %.3f deg, rms %.2f m over %.0f fixes", out.enu.yaw_rad * kRadToDeg,
             out.enu.yaw_sigma_rad * kRadToDeg, out.enu.rms_horizontal_m, out.enu.pairs_used);
    s += fmt(" (%.0f dropped), origin %.7f %.7f", out.enu.pairs_dropped, out.origin.lat_deg,
             out.origin.lon_deg);
    if (out.enu_yaw_from_mag) s += ", yaw from the magnetometer";
  } else {
    s += "none (" + out.enu.reason + ")";
  }
  if (out.mag_valid && out.enu_valid && !out.enu_yaw_from_mag) {
    // Two headings of the same frame: they differ by the declination error only. More points at a
    // wrong declination, a wrong T_imu_cam or a disturbed magnetometer (mag_heading.hpp).
    s += fmt("; mag - ENU psi %.2f deg", wrap_pi(out.mag.yaw_enu_world_rad - out.enu.yaw_rad) * kRadToDeg);
  }
  out.summary = s;
  return out;
}

CurrentSensorPriors::CurrentSensorPriors(const RelocalizationPriorsConfig& config)
    : config_(config), mag_(config.mag) {
  const RelocalizationPriorsConfig defaults;
  if (!positive_finite(config_.sigma_h_m)) config_.sigma_h_m = defaults.sigma_h_m;
  if (!positive_finite(config_.sigma_v_m)) config_.sigma_v_m = defaults.sigma_v_m;
  if (!config_.antenna_imu_m.allFinite()) config_.antenna_imu_m = defaults.antenna_imu_m;
  if (config_.gnss_capacity < 1) config_.gnss_capacity = defaults.gnss_capacity;
  fixes_.resize(static_cast<size_t>(config_.gnss_capacity));
  p_world_.reserve(fixes_.size());
  p_enu_.reserve(fixes_.size());
}

void CurrentSensorPriors::add_mag(const hal::MagSample& sample, const Eigen::Matrix3d& R_world_imu) {
  mag_.add(sample, R_world_imu);
}

void CurrentSensorPriors::add_gnss(const hal::GnssFix& fix, const Eigen::Vector3d& p_world_antenna_m) {
  if (!fix.has_3d_fix() || !std::isfinite(fix.lat_deg) || !std::isfinite(fix.lon_deg) ||
      !std::isfinite(fix.height_m) || !p_world_antenna_m.allFinite()) {
    ++gnss_rejected_;
    return;
  }
  Fix f;
  f.t_ns = fix.t_ns;
  f.geodetic = {fix.lat_deg, fix.lon_deg, fix.height_m};
  f.p_world_antenna_m = p_world_antenna_m;
  const size_t cap = fixes_.size();
  fixes_[(gnss_head_ + gnss_count_) % cap] = f;
  if (gnss_count_ < cap) {
    ++gnss_count_;
  } else {
    gnss_head_ = (gnss_head_ + 1) % cap;
  }
}

void CurrentSensorPriors::reset() {
  mag_.reset();
  gnss_head_ = gnss_count_ = 0;
  gnss_rejected_ = 0;
}

std::string CurrentSensorPriors::fill(const PriorSensorFrames& prior, const Eigen::Isometry3d& T_world_cam,
                                      RelocalizationQuery* query) const {
  query->yaw_valid = false;
  query->yaw_prior_rad = query->yaw_sigma_rad = 0;
  query->position = PositionPrior{};
  const Eigen::Vector3d p_world_cam = T_world_cam.translation();
  // The prior's ENU yaw sigma (the magnetometer's when the fit took its yaw).
  const double prior_enu_yaw_sigma = prior.enu_yaw_from_mag ? prior.mag.sigma_rad : prior.enu.yaw_sigma_rad;

  // Yaw: the two runs' magnetometer headings.
  std::string yaw_text;
  double psi_current_enu = std::numeric_limits<double>::quiet_NaN();  // for the GNSS fit
  double psi_current_sigma = 0;
  if (!config_.use_mag) {
    yaw_text = "yaw: off (use_mag false)";
  } else if (!prior.mag_valid) {
    yaw_text = "yaw: none, the prior map has no magnetometer heading (" + prior.mag.reason + ")";
  } else {
    const estimation::MagHeadingResult current = mag_.result();
    auto rel = estimation::relative_yaw_prior_current(prior.mag, current);
    if (!rel.ok()) {
      yaw_text = "yaw: none, " + rel.status().message();
    } else {
      query->yaw_valid = true;
      query->yaw_prior_rad = rel->yaw_prior_current_rad;
      query->yaw_sigma_rad = rel->sigma_rad;
      yaw_text = fmt("yaw: magnetometer %.2f deg sigma %.2f deg (current psi %.2f deg from %.0f samples)",
                     rel->yaw_prior_current_rad * kRadToDeg, rel->sigma_rad * kRadToDeg,
                     current.yaw_enu_world_rad * kRadToDeg, static_cast<double>(current.used));
      if (prior.enu_valid) {
        // psi of the current world in the prior's ENU: the prior's GNSS yaw plus the relative
        // magnetometer yaw (a declination error common to both runs cancels).
        psi_current_enu = wrap_pi(prior.enu.yaw_rad + rel->yaw_prior_current_rad);
        psi_current_sigma = std::hypot(rel->sigma_rad, prior_enu_yaw_sigma);
      }
    }
  }

  // Position: the current fixes in the prior's ENU, then in the prior frame.
  std::string pos_text;
  if (!config_.use_gnss) {
    pos_text = "position: off (use_gnss false)";
  } else if (!prior.enu_valid) {
    pos_text = "position: none, the prior map is not placed in ENU (" + prior.enu.reason + ")";
  } else if (gnss_count_ == 0) {
    pos_text = "position: none, no 3D GNSS fix in this run yet";
  } else {
    p_world_.clear();
    p_enu_.clear();
    for (size_t i = 0; i < gnss_count_; ++i) {
      const Fix& f = fix_at(i);
      p_world_.push_back(f.p_world_antenna_m);
      p_enu_.push_back(core::geodetic_to_enu(f.geodetic, prior.origin));
    }
    const Eigen::Isometry3d T_prior_enu = prior.enu.T_enu_world.inverse();
    // The prior's placement: its residual, and a GNSS bias correlated over the prior's track that the
    // residuals cannot show (up to sigma_h; averaging over its fixes would be over-confident).
    const double rms_prior = std::hypot(prior.enu.rms_horizontal_m, config_.sigma_h_m);
    // The prior's yaw uncertainty, levered by the distance from its track's centroid.
    double prior_lever = 0;
    auto finish_sigma = [&](const Eigen::Vector3d& p_prior_m, double extra2) {
      prior_lever = prior_enu_yaw_sigma * (p_prior_m - prior.p_prior_antenna_centroid_m).head<2>().norm();
      return std::sqrt(config_.sigma_h_m * config_.sigma_h_m + rms_prior * rms_prior +
                       prior_lever * prior_lever + extra2);
    };
    estimation::GnssAlignment fit;
    bool yaw_from_track = false;
    if (std::isfinite(psi_current_enu)) {
      fit = estimation::fit_T_enu_world(p_world_, p_enu_, config_.sigma_h_m, config_.sigma_v_m,
                                        psi_current_enu, config_.gnss);
    } else {
      fit = estimation::fit_T_enu_world(p_world_, p_enu_, config_.sigma_h_m, config_.sigma_v_m,
                                        std::numeric_limits<double>::quiet_NaN(), config_.gnss);
      yaw_from_track = fit.valid;
      if (yaw_from_track) psi_current_sigma = fit.yaw_sigma_rad;
    }
    if (fit.valid) {
      Eigen::Vector3d c = Eigen::Vector3d::Zero();
      for (const Eigen::Vector3d& p : p_world_) c += p;
      c /= static_cast<double>(p_world_.size());
      const double lever = psi_current_sigma * (p_world_cam - c).head<2>().norm();
      const Eigen::Isometry3d T_prior_world = T_prior_enu * fit.T_enu_world;
      query->position.valid = true;
      query->position.p_prior_m = T_prior_world * p_world_cam;
      query->position.sigma_m = finish_sigma(query->position.p_prior_m, lever * lever);
      pos_text = fmt("position: GNSS fit of %.0f fixes (rms %.2f m), sigma %.2f m, yaw ", fit.pairs_used,
                     fit.rms_horizontal_m, query->position.sigma_m);
      pos_text += yaw_from_track ? "from the current track" : "from the magnetometer";
      if (yaw_from_track && !query->yaw_valid && config_.use_gnss) {
        // The current track fixes the yaw: a GNSS yaw prior (the two runs' ENU yaws).
        query->yaw_valid = true;
        query->yaw_prior_rad = wrap_pi(fit.yaw_rad - prior.enu.yaw_rad);
        query->yaw_sigma_rad = std::hypot(fit.yaw_sigma_rad, prior_enu_yaw_sigma);
        yaw_text += fmt("; yaw from the GNSS tracks %.2f deg sigma %.2f deg",
                        query->yaw_prior_rad * kRadToDeg, query->yaw_sigma_rad * kRadToDeg);
      }
    } else {
      // No yaw: the newest fix alone; the camera's horizontal offset from it is of unknown direction.
      const Fix& newest = fix_at(gnss_count_ - 1);
      const Eigen::Vector3d offset_world = p_world_cam - newest.p_world_antenna_m;
      const double d = offset_world.head<2>().norm();
      Eigen::Vector3d p = T_prior_enu * p_enu_.back();
      p.z() += offset_world.z();
      query->position.valid = true;
      query->position.p_prior_m = p;
      query->position.sigma_m = finish_sigma(p, d * d);
      pos_text = fmt("position: newest GNSS fix, camera %.2f m from its antenna, sigma %.2f m (", d,
                     query->position.sigma_m);
      pos_text += "no yaw for a fit: " + fit.reason + ")";
    }
  }
  return yaw_text + "; " + pos_text;
}

}  // namespace hwr::recon
