#include "hwr/sim/mag_synth.hpp"

#include <algorithm>
#include <cmath>

#include "hwr/core/time.hpp"
#include "hwr/sim/random.hpp"
#include "hwr/sim/sample_times.hpp"

namespace hwr::sim {
namespace {

bool is_steel(Material m) { return m == Material::kSteel || m == Material::kRustySteel; }

// Dipoles evenly spread along a segment of the given length centred at T * 0 along T's x axis.
void add_chain(const Eigen::Isometry3d& T_scene_obj, const Eigen::Vector3d& axis_obj, double length_m,
               const MagSpec& spec, const Eigen::Vector3d& direction, std::vector<MagDipole>* out) {
  const MagDisturbanceSpec& d = spec.disturbance;
  const int n = std::max(1, static_cast<int>(std::ceil(length_m / d.spacing_m)));
  const double piece = length_m / n;
  for (int i = 0; i < n; ++i) {
    const double x = -0.5 * length_m + (i + 0.5) * piece;
    MagDipole dp;
    dp.p_scene_m = T_scene_obj * (x * axis_obj);
    dp.moment_uT_m3 = d.moment_per_m_uT_m3 * piece * direction;
    out->push_back(dp);
  }
}

}  // namespace

std::vector<MagDipole> mag_dipoles_for_scene(const SceneSpec& scene, const MagSpec& spec, uint64_t seed) {
  std::vector<MagDipole> out;
  if (!spec.disturbance.enabled || spec.disturbance.moment_per_m_uT_m3 == 0.0) return out;
  const Eigen::Vector3d induced = spec.earth_field_scene_uT.normalized();
  uint64_t object = 0;
  // Magnetisation direction of one object: mostly induced by (parallel to) the Earth field, plus
  // a seeded remanent part.
  auto direction = [&]() {
    Rng rng(derive_seed(seed, RandomStream::kMagDisturbers, object++));
    const Eigen::Vector3d rem = normal3(&rng).normalized();
    const double f = spec.disturbance.remanent_fraction;
    return ((1.0 - f) * induced + f * rem).normalized();
  };
  for (const IBeamSpec& b : scene.beams) {
    add_chain(b.T_scene_beam, Eigen::Vector3d::UnitX(), b.length_m, spec, direction(), &out);
  }
  for (const WeldJointSpec& j : scene.joints) {
    // Both plates of the joint lie along the seam (joint x axis), starting at the joint origin.
    Eigen::Isometry3d T_scene_mid = j.T_scene_joint;
    T_scene_mid.translation() = j.T_scene_joint * Eigen::Vector3d(0.5 * j.length_m, 0.0, 0.0);
    add_chain(T_scene_mid, Eigen::Vector3d::UnitX(), j.length_m, spec, direction(), &out);
    add_chain(T_scene_mid, Eigen::Vector3d::UnitX(), j.length_m, spec, direction(), &out);
  }
  for (const BoxSpec& b : scene.boxes) {
    if (!is_steel(b.material)) continue;
    int axis = 0;
    b.size_m.maxCoeff(&axis);
    add_chain(b.T_scene_box, Eigen::Vector3d::Unit(axis), b.size_m[axis], spec, direction(), &out);
  }
  for (const PipeSpec& p : scene.pipes) {
    if (!is_steel(p.material)) continue;
    add_chain(p.T_scene_pipe, Eigen::Vector3d::UnitZ(), p.length_m, spec, direction(), &out);
  }
  return out;
}

Eigen::Vector3d magnetic_field_scene_uT(const MagSpec& spec, const std::vector<MagDipole>& dipoles,
                                        const Eigen::Vector3d& p_scene_m) {
  Eigen::Vector3d b = spec.earth_field_scene_uT;
  const MagDisturbanceSpec& d = spec.disturbance;
  if (!d.enabled) return b;
  for (const MagDipole& dp : dipoles) {
    const Eigen::Vector3d r = p_scene_m - dp.p_scene_m;
    const double dist = r.norm();
    if (dist >= d.cutoff_end_m) continue;
    double w = 1.0;
    if (dist > d.cutoff_begin_m) {
      // 1 - smoothstep: the fade has zero slope at both ends, so the field stays smooth.
      const double x = (dist - d.cutoff_begin_m) / (d.cutoff_end_m - d.cutoff_begin_m);
      w = 1.0 - x * x * (3.0 - 2.0 * x);
    }
    const double re = std::max(dist, d.min_distance_m);
    const Eigen::Vector3d rhat = dist > 0.0 ? Eigen::Vector3d(r / dist) : Eigen::Vector3d::UnitZ();
    b += w * (3.0 * dp.moment_uT_m3.dot(rhat) * rhat - dp.moment_uT_m3) / (re * re * re);
  }
  return b;
}

std::vector<hal::MagSample> synthesize_mag(const Trajectory& trajectory, const MagSpec& spec,
                                           const std::vector<MagDipole>& dipoles, uint64_t seed,
                                           double duration_s, int64_t t0_ns) {
  std::vector<hal::MagSample> out;
  if (!spec.enabled) return out;
  const std::vector<int64_t> offsets = sample_offsets_ns(spec.rate_hz, duration_s);
  out.resize(offsets.size());
  Rng rng(derive_seed(seed, RandomStream::kMag));
  for (size_t k = 0; k < offsets.size(); ++k) {
    const TrajectoryState st = trajectory.evaluate(core::ns_to_s(offsets[k]));
    const Eigen::Vector3d b_scene = magnetic_field_scene_uT(spec, dipoles, st.T_scene_imu.translation());
    hal::MagSample& m = out[k];
    m.t_ns = t0_ns + offsets[k];
    m.field_uT = st.T_scene_imu.linear().transpose() * b_scene + spec.hard_iron_uT;
    if (spec.noise_enabled) m.field_uT += spec.noise_sigma_uT * normal3(&rng);
  }
  return out;
}

}  // namespace hwr::sim
