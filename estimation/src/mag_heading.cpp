#include "hwr/estimation/mag_heading.hpp"

#include <algorithm>
#include <array>
#include <cstdio>

#include <Eigen/Geometry>

namespace hwr::estimation {
namespace {

// Gate outcome of one record in result().
enum Gate : uint8_t { kHorizontal, kField, kInclination, kHeadingOut, kHeadingIn };

// (-pi, pi].
double wrap_pi(double a) {
  double r = std::remainder(a, 2.0 * M_PI);
  if (r <= -M_PI) r += 2.0 * M_PI;
  return r;
}

// Centre of the heaviest window of `window_bins` consecutive 1-degree bins (circular): the mode
// of the headings at the gate's resolution, the seed of the consistency gate.
double heading_mode(const std::array<double, 360>& hist, int window_bins) {
  window_bins = std::clamp(window_bins, 1, 360);
  double sum = 0.0;
  for (int i = 0; i < window_bins; ++i) sum += hist[i];
  double best = sum;
  int best_start = 0;
  for (int start = 1; start < 360; ++start) {
    sum += hist[(start + window_bins - 1) % 360];
    sum -= hist[start - 1];
    if (sum > best) {
      best = sum;
      best_start = start;
    }
  }
  const double bin_rad = 2.0 * M_PI / 360.0;
  return wrap_pi(-M_PI + (best_start + 0.5 * window_bins) * bin_rad);
}

bool is_rotation(const Eigen::Matrix3d& R) {
  return R.allFinite() && (R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() < 1e-6 &&
         R.determinant() > 0.0;
}

}  // namespace

MagHeadingEstimator::MagHeadingEstimator(const MagHeadingConfig& config)
    : config_(config),
      records_(std::max<size_t>(config.capacity, 2)),
      weight_(records_.size()),
      order_(records_.size()),
      value_weight_(records_.size()),
      gate_(records_.size()) {
  if (!(config_.place_cell_m >= 1e-3)) config_.place_cell_m = 1e-3;
}

void MagHeadingEstimator::reset() {
  count_ = 0;
  stride_ = 1;
  seen_ = valid_seen_ = invalid_ = 0;
}

void MagHeadingEstimator::add(const hal::MagSample& sample, const Eigen::Isometry3d& T_world_imu) {
  const Eigen::Vector3d p = T_world_imu.translation();
  if (!p.allFinite()) {
    ++seen_;
    ++invalid_;
    return;
  }
  // Pack the place cube's integer coordinates, 21 bits each (+-1e6 cubes: +-500 km at 0.5 m).
  constexpr int64_t kHalf = int64_t{1} << 20;
  int64_t place = 0;
  for (int i = 0; i < 3; ++i) {
    const double c = std::floor(p[i] / config_.place_cell_m);
    const int64_t ci =
        static_cast<int64_t>(std::clamp(c, -static_cast<double>(kHalf), static_cast<double>(kHalf - 1)));
    place = (place << 21) | (ci + kHalf);
  }
  add_record(sample, T_world_imu.linear(), place);
}

void MagHeadingEstimator::add(const hal::MagSample& sample, const Eigen::Matrix3d& R_world_imu) {
  add_record(sample, R_world_imu, kNoPlace);
}

void MagHeadingEstimator::add_record(const hal::MagSample& sample, const Eigen::Matrix3d& R_world_imu,
                                     int64_t place) {
  ++seen_;
  if (!sample.field_uT.allFinite() || !is_rotation(R_world_imu)) {
    ++invalid_;
    return;
  }
  const uint64_t k = valid_seen_++;
  if (k % stride_ != 0) return;
  if (count_ == records_.size()) {
    // Keep every second record: the kept ones are the valid samples with index % (2 stride) == 0.
    for (size_t i = 0; 2 * i < count_; ++i) records_[i] = records_[2 * i];
    count_ = (count_ + 1) / 2;
    stride_ *= 2;
    if (k % stride_ != 0) return;
  }
  const Eigen::Vector3d b_world = R_world_imu * (sample.field_uT - config_.hard_iron_imu_uT);
  const double horizontal = std::hypot(b_world.x(), b_world.y());
  Record& r = records_[count_++];
  // psi = pi/2 - D - atan2(b_y, b_x) (header comment).
  r.yaw_enu_world_rad = wrap_pi(0.5 * M_PI - config_.declination_rad - std::atan2(b_world.y(), b_world.x()));
  r.field_uT = b_world.norm();
  r.inclination_rad = std::atan2(-b_world.z(), horizontal);
  r.horizontal_uT = horizontal;
  r.place = place;
}

// weight_[i] = 1 / (records in record i's place); order_ = the records sorted by place.
void MagHeadingEstimator::compute_weights() const {
  for (size_t i = 0; i < count_; ++i) order_[i] = static_cast<uint32_t>(i);
  std::sort(order_.begin(), order_.begin() + static_cast<std::ptrdiff_t>(count_),
            [this](uint32_t a, uint32_t b) { return records_[a].place < records_[b].place; });
  size_t begin = 0;
  while (begin < count_) {
    size_t end = begin + 1;
    while (end < count_ && records_[order_[end]].place == records_[order_[begin]].place) ++end;
    const double w = 1.0 / static_cast<double>(end - begin);
    for (size_t j = begin; j < end; ++j) weight_[order_[j]] = w;
    begin = end;
  }
}

// The value at which the cumulative weight reaches half the total (lower weighted median).
double MagHeadingEstimator::weighted_median(double Record::*field) const {
  double total = 0.0;
  for (size_t i = 0; i < count_; ++i) {
    value_weight_[i] = {records_[i].*field, weight_[i]};
    total += weight_[i];
  }
  std::sort(value_weight_.begin(), value_weight_.begin() + static_cast<std::ptrdiff_t>(count_));
  double cumulative = 0.0;
  for (size_t i = 0; i < count_; ++i) {
    cumulative += value_weight_[i].second;
    if (cumulative >= 0.5 * total) return value_weight_[i].first;
  }
  return value_weight_[count_ - 1].first;
}

MagHeadingResult MagHeadingEstimator::result(std::vector<bool>* used_per_stored) const {
  MagHeadingResult out;
  out.seen = seen_;
  out.invalid_input = invalid_;
  out.stored = count_;
  if (used_per_stored != nullptr) used_per_stored->assign(count_, false);
  char msg[640];
  if (count_ == 0) {
    std::snprintf(
        msg, sizeof(msg),
        "no magnetometer samples (%llu given, %llu with a non-finite value or pose or a non-rotation "
        "attitude)",
        static_cast<unsigned long long>(seen_), static_cast<unsigned long long>(invalid_));
    out.reason = msg;
    return out;
  }
  compute_weights();

  // References of gates 2 and 3: configured, or the weighted medians of the stored samples.
  out.field_ref_uT =
      config_.expected_field_uT > 0.0 ? config_.expected_field_uT : weighted_median(&Record::field_uT);
  out.inclination_ref_rad = std::isfinite(config_.expected_inclination_rad)
                                ? config_.expected_inclination_rad
                                : weighted_median(&Record::inclination_rad);

  // Gates 1-3, and the weighted heading histogram of the survivors.
  std::array<double, 360> hist{};
  size_t candidates = 0;
  double stored_weight = 0.0;
  bool placed = false;  // some sample came with a position: weights are per place
  for (size_t i = 0; i < count_; ++i) {
    const Record& r = records_[i];
    stored_weight += weight_[i];
    placed |= r.place != kNoPlace;
    if (r.horizontal_uT < config_.min_horizontal_field_uT) {
      gate_[i] = kHorizontal;
      ++out.rejected_horizontal;
    } else if (std::abs(r.field_uT - out.field_ref_uT) > config_.field_tolerance_frac * out.field_ref_uT) {
      gate_[i] = kField;
      ++out.rejected_field;
    } else if (std::abs(r.inclination_rad - out.inclination_ref_rad) > config_.inclination_tolerance_rad) {
      gate_[i] = kInclination;
      ++out.rejected_inclination;
    } else {
      gate_[i] = kHeadingOut;
      ++candidates;
      const int bin = static_cast<int>(std::floor((r.yaw_enu_world_rad + M_PI) * (180.0 / M_PI)));
      hist[static_cast<size_t>(std::clamp(bin, 0, 359))] += weight_[i];
    }
  }

  // Gate 4: seed at the weighted mode, then re-gate around the weighted circular mean until the
  // set is stable.
  double c = 0.0, s = 0.0, w_sum = 0.0, w2_sum = 0.0, h_sum = 0.0;
  size_t used = 0;
  if (candidates > 0) {
    const double gate = config_.heading_gate_rad;
    double centre = heading_mode(hist, static_cast<int>(std::lround(2.0 * gate * 180.0 / M_PI)));
    for (int iter = 0; iter < 50; ++iter) {
      bool changed = false;
      c = s = w_sum = w2_sum = h_sum = 0.0;
      used = 0;
      for (size_t i = 0; i < count_; ++i) {
        if (gate_[i] != kHeadingOut && gate_[i] != kHeadingIn) continue;
        const double psi = records_[i].yaw_enu_world_rad;
        const Gate g = std::abs(wrap_pi(psi - centre)) <= gate ? kHeadingIn : kHeadingOut;
        changed |= g != gate_[i];
        gate_[i] = g;
        if (g != kHeadingIn) continue;
        const double w = weight_[i];
        c += w * std::cos(psi);
        s += w * std::sin(psi);
        w_sum += w;
        w2_sum += w * w;
        h_sum += w * records_[i].horizontal_uT;
        ++used;
      }
      if (used == 0 || (!changed && iter > 0)) break;
      centre = std::atan2(s, c);
    }
  }
  out.used = used;
  out.rejected_heading = candidates - used;
  out.used_fraction = used > 0 && stored_weight > 0.0 ? std::min(1.0, w_sum / stored_weight) : 0.0;
  if (used_per_stored != nullptr) {
    for (size_t i = 0; i < count_; ++i) (*used_per_stored)[i] = gate_[i] == kHeadingIn;
  }
  // Distinct places among the used samples (order_ is sorted by place).
  int64_t last_place = 0;
  for (size_t j = 0; j < count_; ++j) {
    const Record& r = records_[order_[j]];
    if (gate_[order_[j]] != kHeadingIn || (out.places > 0 && r.place == last_place)) continue;
    ++out.places;
    last_place = r.place;
  }

  if (used < std::max<size_t>(config_.min_samples, 1)) {
    std::snprintf(
        msg, sizeof(msg),
        "only %zu of %zu magnetometer samples undisturbed, need %zu (rejected: %zu horizontal field "
        "< %.3g uT, %zu |B| off %.3g uT by > %.0f%%, %zu dip off %.1f deg by > %.1f deg, %zu heading "
        "off the consensus by > %.1f deg)",
        used, count_, config_.min_samples, out.rejected_horizontal, config_.min_horizontal_field_uT,
        out.rejected_field, out.field_ref_uT, 100.0 * config_.field_tolerance_frac, out.rejected_inclination,
        out.inclination_ref_rad * 180.0 / M_PI, config_.inclination_tolerance_rad * 180.0 / M_PI,
        out.rejected_heading, config_.heading_gate_rad * 180.0 / M_PI);
    out.reason = msg;
    return out;
  }
  if (out.used_fraction < config_.min_used_fraction) {
    // "Majority" (header comment): the agreeing samples are a minority of the places.
    std::snprintf(
        msg, sizeof(msg),
        "the %zu of %zu magnetometer samples that agree on one field and heading are only %.1f%% of "
        "the %s (need %.0f%%; rejected: %zu |B| off %.3g uT, %zu dip off %.1f deg, %zu heading off the "
        "consensus): most places are disturbed, or the attitudes given with the samples are wrong "
        "(e.g. a wrong camera-IMU extrinsic T_imu_cam)",
        used, count_, 100.0 * out.used_fraction, placed ? "visited places" : "samples",
        100.0 * config_.min_used_fraction, out.rejected_field, out.field_ref_uT, out.rejected_inclination,
        out.inclination_ref_rad * 180.0 / M_PI, out.rejected_heading);
    out.reason = msg;
    return out;
  }

  // Weighted circular mean and its uncertainty (header comment).
  out.resultant_length = std::min(1.0, std::hypot(c, s) / w_sum);
  out.effective_samples = w_sum * w_sum / w2_sum;
  out.horizontal_field_uT = h_sum / w_sum;
  const double circ_std = std::sqrt(std::max(0.0, -2.0 * std::log(std::max(out.resultant_length, 1e-300))));
  const double noise_std = config_.noise_sigma_uT / out.horizontal_field_uT;
  const double per_sample = std::max(circ_std, noise_std);
  out.yaw_enu_world_rad = wrap_pi(std::atan2(s, c));
  out.sigma_rad = std::sqrt(per_sample * per_sample / out.effective_samples +
                            config_.sigma_floor_rad * config_.sigma_floor_rad);
  out.valid = true;
  return out;
}

core::Expected<MagRelativeYaw> relative_yaw_prior_current(const MagHeadingResult& prior,
                                                          const MagHeadingResult& current) {
  if (!prior.valid) return core::Unavailable("no magnetometer heading for the prior run: " + prior.reason);
  if (!current.valid)
    return core::Unavailable("no magnetometer heading for the current run: " + current.reason);
  MagRelativeYaw out;
  out.yaw_prior_current_rad = wrap_pi(current.yaw_enu_world_rad - prior.yaw_enu_world_rad);
  out.sigma_rad = std::hypot(prior.sigma_rad, current.sigma_rad);
  out.R_prior_current =
      Eigen::AngleAxisd(out.yaw_prior_current_rad, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  return out;
}

}  // namespace hwr::estimation
