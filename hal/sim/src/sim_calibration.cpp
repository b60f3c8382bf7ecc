#include "hwr/sim/sim_calibration.hpp"

#include "hwr/core/config.hpp"
#include "hwr/sim/scenario.hpp"
#include "sim_text.hpp"

namespace hwr::sim {

using text::list;
using text::num;

SimCalibration make_sim_calibration(const ScenarioSpec& spec, const Eigen::Isometry3d& T_scene_world) {
  SimCalibration c;
  c.scenario = spec.name;
  c.seed = spec.seed;
  c.start_time_ns = spec.start_time_ns;
  c.intrinsics = spec.camera.intrinsics;
  c.camera_rate_hz = spec.camera.rate_hz;
  c.depth_scale = spec.camera.depth_scale;
  c.T_imu_cam = camera_T_imu_cam(spec.camera);
  c.stereo = spec.camera.stereo;
  c.baseline_m = spec.camera.stereo ? spec.camera.baseline_m : 0.0;
  c.imu_rate_hz = spec.imu.rate_hz;
  c.gravity_mps2 = spec.imu.gravity_mps2;
  c.imu_noise_enabled = spec.imu.noise.enabled;
  c.gyro_noise_density = spec.imu.noise.gyro_noise_density;
  c.accel_noise_density = spec.imu.noise.accel_noise_density;
  c.gyro_random_walk = spec.imu.noise.gyro_random_walk;
  c.accel_random_walk = spec.imu.noise.accel_random_walk;
  c.mag_enabled = spec.mag.enabled;
  c.mag_rate_hz = spec.mag.enabled ? spec.mag.rate_hz : 0.0;
  c.mag_field_scene_uT = spec.mag.earth_field_scene_uT;
  c.mag_field_world_uT = T_scene_world.linear().transpose() * spec.mag.earth_field_scene_uT;
  c.mag_hard_iron_uT = spec.mag.hard_iron_uT;
  c.mag_noise_sigma_uT = spec.mag.noise_enabled ? spec.mag.noise_sigma_uT : 0.0;
  c.gnss_enabled = spec.gnss.enabled;
  c.gnss_rate_hz = spec.gnss.enabled ? spec.gnss.rate_hz : 0.0;
  c.gnss_origin = spec.gnss.origin;
  c.gnss_antenna_imu_m = spec.gnss.antenna_imu_m;
  c.gnss_sigma_h_m = spec.gnss.sigma_h_m;
  c.gnss_sigma_v_m = spec.gnss.sigma_v_m;
  c.T_scene_world = T_scene_world;
  return c;
}

std::string sim_calibration_to_yaml(const SimCalibration& c) {
  std::string y;
  auto kv = [&y](int indent, const std::string& k, const std::string& v) {
    y += std::string(indent, ' ') + k + (v.empty() ? ":\n" : ": " + v + "\n");
  };
  auto b = [](bool x) { return std::string(x ? "true" : "false"); };
  y += "# hwr-sim calibration. Frames: scene = ENU at gnss.origin; world = gravity-aligned first IMU\n";
  y += "# frame (p_scene = T_scene_world * p_world); imu = x forward, y left, z up; cam = OpenCV.\n";
  y += "# Poses are 4x4 row-major. Depth PNG raw value / depth_scale = metres along the optical axis.\n";
  kv(0, "scenario", text::quoted(c.scenario));
  kv(0, "seed", std::to_string(c.seed));
  kv(0, "start_time_ns", std::to_string(c.start_time_ns));
  kv(0, "camera", "");
  kv(2, "width", std::to_string(c.intrinsics.width));
  kv(2, "height", std::to_string(c.intrinsics.height));
  kv(2, "fx", num(c.intrinsics.fx));
  kv(2, "fy", num(c.intrinsics.fy));
  kv(2, "cx", num(c.intrinsics.cx));
  kv(2, "cy", num(c.intrinsics.cy));
  kv(2, "distortion", list(c.intrinsics.distortion.data(), 5));
  kv(2, "rate_hz", num(c.camera_rate_hz));
  kv(2, "depth_scale", num(c.depth_scale));
  kv(2, "T_imu_cam", text::matrix16(c.T_imu_cam));
  kv(2, "stereo", b(c.stereo));
  kv(2, "baseline_m", num(c.baseline_m));
  kv(0, "imu", "");
  kv(2, "rate_hz", num(c.imu_rate_hz));
  kv(2, "gravity_mps2", num(c.gravity_mps2));
  kv(2, "noise_enabled", b(c.imu_noise_enabled));
  kv(2, "gyro_noise_density", num(c.gyro_noise_density));
  kv(2, "accel_noise_density", num(c.accel_noise_density));
  kv(2, "gyro_random_walk", num(c.gyro_random_walk));
  kv(2, "accel_random_walk", num(c.accel_random_walk));
  kv(0, "mag", "");
  kv(2, "enabled", b(c.mag_enabled));
  kv(2, "rate_hz", num(c.mag_rate_hz));
  kv(2, "field_scene_uT", list(c.mag_field_scene_uT));
  kv(2, "field_world_uT", list(c.mag_field_world_uT));
  kv(2, "hard_iron_uT", list(c.mag_hard_iron_uT));
  kv(2, "noise_sigma_uT", num(c.mag_noise_sigma_uT));
  kv(0, "gnss", "");
  kv(2, "enabled", b(c.gnss_enabled));
  kv(2, "rate_hz", num(c.gnss_rate_hz));
  kv(2, "origin", "");
  kv(4, "lat_deg", num(c.gnss_origin.lat_deg));
  kv(4, "lon_deg", num(c.gnss_origin.lon_deg));
  kv(4, "height_m", num(c.gnss_origin.height_m));
  kv(2, "antenna_imu_m", list(c.gnss_antenna_imu_m));
  kv(2, "sigma_h_m", num(c.gnss_sigma_h_m));
  kv(2, "sigma_v_m", num(c.gnss_sigma_v_m));
  kv(0, "T_scene_world", text::matrix16(c.T_scene_world));
  return y;
}

core::Status save_sim_calibration(const std::string& path, const SimCalibration& calib) {
  return text::write_file_atomic(path, sim_calibration_to_yaml(calib));
}

namespace {
void read_pose16(core::ConfigMap& m, const char* key, Eigen::Isometry3d* T) {
  std::vector<double> v;
  m.require(key, &v);
  if (!m.has(key)) return;
  if (!text::isometry_from16(v, T)) {
    m.record_error(key, "expected 16 numbers of a 4x4 rigid transform (row-major, last row 0 0 0 1)");
  }
}
}  // namespace

core::Expected<SimCalibration> parse_sim_calibration(const std::string& yaml_text,
                                                     const std::string& source_name) {
  auto doc = core::ConfigDocument::parse(yaml_text, source_name);
  if (!doc.ok()) return doc.status();
  core::ConfigMap root = doc->root();
  SimCalibration c;
  root.require("scenario", &c.scenario).require("seed", &c.seed).require("start_time_ns", &c.start_time_ns);
  core::ConfigMap cam = root.child("camera");
  cam.require("width", &c.intrinsics.width).require("height", &c.intrinsics.height);
  cam.require("fx", &c.intrinsics.fx).require("fy", &c.intrinsics.fy);
  cam.require("cx", &c.intrinsics.cx).require("cy", &c.intrinsics.cy);
  std::vector<double> dist;
  cam.require("distortion", &dist);
  if (cam.has("distortion") && dist.size() != 5) {
    cam.record_error("distortion", "expected 5 numbers (k1 k2 p1 p2 k3)");
  } else {
    for (size_t i = 0; i < dist.size(); ++i) c.intrinsics.distortion[i] = dist[i];
  }
  cam.require("rate_hz", &c.camera_rate_hz).require("depth_scale", &c.depth_scale);
  read_pose16(cam, "T_imu_cam", &c.T_imu_cam);
  cam.require("stereo", &c.stereo).require("baseline_m", &c.baseline_m);
  core::ConfigMap imu = root.child("imu");
  imu.require("rate_hz", &c.imu_rate_hz).require("gravity_mps2", &c.gravity_mps2);
  imu.require("noise_enabled", &c.imu_noise_enabled);
  imu.require("gyro_noise_density", &c.gyro_noise_density)
      .require("accel_noise_density", &c.accel_noise_density);
  imu.require("gyro_random_walk", &c.gyro_random_walk).require("accel_random_walk", &c.accel_random_walk);
  core::ConfigMap mag = root.child("mag");
  mag.require("enabled", &c.mag_enabled).require("rate_hz", &c.mag_rate_hz);
  mag.require("field_scene_uT", &c.mag_field_scene_uT).require("field_world_uT", &c.mag_field_world_uT);
  mag.require("hard_iron_uT", &c.mag_hard_iron_uT).require("noise_sigma_uT", &c.mag_noise_sigma_uT);
  core::ConfigMap gnss = root.child("gnss");
  gnss.require("enabled", &c.gnss_enabled).require("rate_hz", &c.gnss_rate_hz);
  core::ConfigMap origin = gnss.child("origin");
  origin.require("lat_deg", &c.gnss_origin.lat_deg).require("lon_deg", &c.gnss_origin.lon_deg);
  origin.require("height_m", &c.gnss_origin.height_m);
  gnss.require("antenna_imu_m", &c.gnss_antenna_imu_m);
  gnss.require("sigma_h_m", &c.gnss_sigma_h_m).require("sigma_v_m", &c.gnss_sigma_v_m);
  read_pose16(root, "T_scene_world", &c.T_scene_world);
  HWR_RETURN_IF_ERROR(doc->finish());
  if (!c.intrinsics.valid()) return core::InvalidArgument(source_name + ": camera intrinsics are not valid");
  return c;
}

core::Expected<SimCalibration> load_sim_calibration(const std::string& path) {
  std::string yaml;
  HWR_RETURN_IF_ERROR(text::read_file(path, &yaml));
  return parse_sim_calibration(yaml, path);
}

}  // namespace hwr::sim
