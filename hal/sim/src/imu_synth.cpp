#include "hwr/sim/imu_synth.hpp"

#include <cmath>

#include "hwr/core/time.hpp"
#include "hwr/sim/random.hpp"
#include "hwr/sim/sample_times.hpp"

namespace hwr::sim {

hal::ImuSample ideal_imu(const TrajectoryState& state, double gravity_mps2) {
  hal::ImuSample s;
  s.gyro_radps = state.omega_imu_radps;
  const Eigen::Vector3d g_scene(0.0, 0.0, -gravity_mps2);
  // Specific force: what an accelerometer measures is acceleration minus gravity, in the body.
  s.accel_mps2 = state.T_scene_imu.linear().transpose() * (state.a_scene_mps2 - g_scene);
  return s;
}

std::vector<ImuRecord> synthesize_imu(const Trajectory& trajectory, const ImuSpec& spec, uint64_t seed,
                                      double duration_s, int64_t t0_ns) {
  const std::vector<int64_t> offsets = sample_offsets_ns(spec.rate_hz, duration_s);
  std::vector<ImuRecord> out(offsets.size());
  Rng rng(derive_seed(seed, RandomStream::kImu));
  const ImuNoiseSpec& nz = spec.noise;
  Eigen::Vector3d bg = nz.enabled ? nz.gyro_bias_initial_radps : Eigen::Vector3d::Zero();
  Eigen::Vector3d ba = nz.enabled ? nz.accel_bias_initial_mps2 : Eigen::Vector3d::Zero();
  const double sqrt_rate = std::sqrt(spec.rate_hz);
  const double sigma_g = nz.gyro_noise_density * sqrt_rate;
  const double sigma_a = nz.accel_noise_density * sqrt_rate;
  auto gauss3 = [&rng]() { return normal3(&rng); };
  for (size_t k = 0; k < offsets.size(); ++k) {
    const TrajectoryState st = trajectory.evaluate(core::ns_to_s(offsets[k]));
    ImuRecord& r = out[k];
    r.sample = ideal_imu(st, spec.gravity_mps2);
    r.sample.t_ns = t0_ns + offsets[k];
    if (nz.enabled) {
      if (k > 0) {
        // Bias random walk over the elapsed step: sigma = density * sqrt(dt).
        const double sqrt_dt = std::sqrt(core::ns_to_s(offsets[k] - offsets[k - 1]));
        bg += nz.gyro_random_walk * sqrt_dt * gauss3();
        ba += nz.accel_random_walk * sqrt_dt * gauss3();
      }
      r.sample.gyro_radps += bg + sigma_g * gauss3();
      r.sample.accel_mps2 += ba + sigma_a * gauss3();
    }
    r.gyro_bias_radps = bg;
    r.accel_bias_mps2 = ba;
  }
  return out;
}

}  // namespace hwr::sim
