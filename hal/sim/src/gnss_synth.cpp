#include "hwr/sim/gnss_synth.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "hwr/core/time.hpp"
#include "hwr/sim/random.hpp"
#include "hwr/sim/sample_times.hpp"

namespace hwr::sim {

std::vector<GnssDropout> gnss_dropouts(const GnssSpec& spec, uint64_t seed, double duration_s) {
  std::vector<GnssDropout> out = spec.dropouts;
  if (spec.random_dropouts_per_min > 0.0) {
    Rng rng(derive_seed(seed, RandomStream::kGnssDropouts));
    const double mean_gap_s = 60.0 / spec.random_dropouts_per_min;
    double t = 0.0;
    for (;;) {
      t += -mean_gap_s * std::log(1.0 - rng.uniform());  // exponential inter-arrival times
      const double len = rng.uniform(spec.random_dropout_min_s, spec.random_dropout_max_s);
      if (t > duration_s) break;
      out.push_back({t, t + len});
      t += len;
    }
  }
  return out;
}

std::vector<GnssRecord> synthesize_gnss(const Trajectory& trajectory, const GnssSpec& spec, uint64_t seed,
                                        double duration_s, int64_t t0_ns) {
  std::vector<GnssRecord> out;
  if (!spec.enabled) return out;
  const std::vector<int64_t> offsets = sample_offsets_ns(spec.rate_hz, duration_s);
  const std::vector<GnssDropout> dropouts = gnss_dropouts(spec, seed, duration_s);
  out.resize(offsets.size());
  Rng rng(derive_seed(seed, RandomStream::kGnss));

  const Eigen::Vector3d sigma(spec.sigma_h_m, spec.sigma_h_m, spec.sigma_v_m);
  const double f = std::clamp(spec.correlated_fraction, 0.0, 1.0);
  const Eigen::Vector3d sigma_gm = std::sqrt(f) * sigma;
  const Eigen::Vector3d sigma_white = std::sqrt(1.0 - f) * sigma;
  const double dt = 1.0 / spec.rate_hz;
  const double phi = spec.correlation_time_s > 0.0 ? std::exp(-dt / spec.correlation_time_s) : 0.0;
  // Start the Gauss-Markov state in its stationary distribution.
  Eigen::Vector3d gm = sigma_gm.cwiseProduct(normal3(&rng));
  int num_sv = (spec.num_sv_min + spec.num_sv_max) / 2;
  const double nan = std::numeric_limits<double>::quiet_NaN();

  for (size_t k = 0; k < offsets.size(); ++k) {
    const double t_s = core::ns_to_s(offsets[k]);
    const TrajectoryState st = trajectory.evaluate(t_s);
    GnssRecord& r = out[k];
    r.antenna_scene_m = st.T_scene_imu * spec.antenna_imu_m;
    if (k > 0) gm = phi * gm + std::sqrt(1.0 - phi * phi) * sigma_gm.cwiseProduct(normal3(&rng));
    const Eigen::Vector3d white = sigma_white.cwiseProduct(normal3(&rng));
    // Satellite count wanders by one now and then (drawn every sample to keep the stream fixed).
    const double u = rng.uniform();
    if (u < 0.02) num_sv = std::max(spec.num_sv_min, num_sv - 1);
    if (u > 0.98) num_sv = std::min(spec.num_sv_max, num_sv + 1);
    r.error_enu_m = spec.noise_enabled ? Eigen::Vector3d(gm + white) : Eigen::Vector3d::Zero();

    r.dropout = std::any_of(dropouts.begin(), dropouts.end(),
                            [t_s](const GnssDropout& d) { return t_s >= d.start_s && t_s < d.end_s; });
    hal::GnssFix& fx = r.fix;
    fx.t_ns = t0_ns + offsets[k];
    if (r.dropout) {
      fx.fix_type = 0;
      fx.num_sv = static_cast<uint8_t>(std::min(num_sv, 3));
      fx.lat_deg = fx.lon_deg = fx.height_m = fx.h_acc_m = fx.v_acc_m = nan;
      continue;
    }
    const core::Geodetic g = core::enu_to_geodetic(r.antenna_scene_m + r.error_enu_m, spec.origin);
    fx.fix_type = 3;
    fx.num_sv = static_cast<uint8_t>(num_sv);
    fx.lat_deg = g.lat_deg;
    fx.lon_deg = g.lon_deg;
    fx.height_m = g.height_m;
    fx.h_acc_m = spec.sigma_h_m;
    fx.v_acc_m = spec.sigma_v_m;
  }
  return out;
}

}  // namespace hwr::sim
