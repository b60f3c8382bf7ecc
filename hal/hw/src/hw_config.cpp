#include "hwr/hal/hw/hw_config.hpp"

#include <cmath>
#include <vector>

#include "hwr/core/config.hpp"
#include "hwr/core/file_io.hpp"
#include "hwr/core/se3.hpp"

namespace hwr::hal::hw {
namespace {

bool is_zed_mode(int w, int h, int fps) {
  // hardware.md: per-eye sizes and the frame rates each one offers.
  if (w == 2208 && h == 1242) return fps == 15;
  if (w == 1920 && h == 1080) return fps == 15 || fps == 30;
  if (w == 1280 && h == 720) return fps == 15 || fps == 30 || fps == 60;
  if (w == 672 && h == 376) return fps == 15 || fps == 30 || fps == 60 || fps == 100;
  return false;
}

void read_pose16(core::ConfigMap& m, const char* key, Eigen::Isometry3d* T) {
  if (!m.has(key)) return;
  std::vector<double> v;
  m.get(key, &v);
  if (v.size() != 16) {
    m.record_error(key, "expected 16 numbers (a 4x4 matrix, row by row)");
    return;
  }
  Eigen::Matrix4d M;
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) M(r, c) = v[static_cast<size_t>(4 * r + c)];
  Eigen::Isometry3d P;
  P.matrix() = M;
  const std::string problem = core::rigid_transform_problem(P);
  if (!problem.empty() || M.row(3) != Eigen::RowVector4d(0, 0, 0, 1)) {
    m.record_error(key, problem.empty() ? "last row must be 0 0 0 1" : problem);
    return;
  }
  *T = P;
}

void read_camera(core::ConfigMap cam, ZedCameraConfig* c) {
  cam.get("enabled", &c->enabled).get("device", &c->device);
  cam.get("eye_width", &c->eye_width).get("eye_height", &c->eye_height).get("fps", &c->fps);
  cam.get("buffers", &c->buffers);
  if (c->enabled) cam.require("calibration", &c->calibration);
  if (!is_zed_mode(c->eye_width, c->eye_height, c->fps)) {
    cam.record_error("eye_width",
                     "the ZED 2i has no mode " + std::to_string(c->eye_width) + "x" +
                         std::to_string(c->eye_height) + "@" + std::to_string(c->fps) +
                         " (2208x1242@15, 1920x1080@15/30, 1280x720@15/30/60, 672x376@15/30/60/100)");
  }
  if (c->buffers < 2 || c->buffers > 32) cam.record_error("buffers", "expected 2..32");
  core::ConfigMap s = cam.child("sgbm");
  StereoSgbmParams& p = c->sgbm;
  s.get("min_disparity", &p.min_disparity).get("num_disparities", &p.num_disparities);
  s.get("block_size", &p.block_size).get("p1", &p.p1).get("p2", &p.p2);
  s.get("disp12_max_diff", &p.disp12_max_diff).get("pre_filter_cap", &p.pre_filter_cap);
  s.get("uniqueness_ratio", &p.uniqueness_ratio).get("speckle_window_size", &p.speckle_window_size);
  s.get("speckle_range", &p.speckle_range).get("full_dp", &p.full_dp);
  s.get("rectify_alpha", &p.rectify_alpha)
      .get("min_depth_m", &p.min_depth_m)
      .get("max_depth_m", &p.max_depth_m);
}

}  // namespace

core::Expected<HwConfig> parse_hw_config(const std::string& yaml_text, const std::string& source_name) {
  auto doc = core::ConfigDocument::parse(yaml_text, source_name);
  if (!doc.ok()) return doc.status();
  core::ConfigMap root = doc->root();
  HwConfig c;
  // Defaults for the ZED 2i at 1280x720: f ~ 530 px, B = 0.12 m; 128 px of disparity reach ~0.5 m.
  c.camera.sgbm.num_disparities = 128;
  read_camera(root.child("camera"), &c.camera);

  core::ConfigMap zs = root.child("zed_sensors");
  zs.get("enabled", &c.zed_sensors);

  std::string imu = "zed";
  root.get("imu", &imu);
  if (imu == "zed") {
    c.imu = ImuKind::kZed;
  } else if (imu == "a9") {
    c.imu = ImuKind::kA9;
  } else {
    root.record_error("imu",
                      "expected 'zed' (the ZED 2i's own IMU) or 'a9' (the Handsfree A9), got '" + imu + "'");
  }

  core::ConfigMap a9 = root.child("a9");
  a9.get("enabled", &c.a9_enabled).get("device", &c.a9_device).get("baud", &c.a9_baud);

  core::ConfigMap g = root.child("gnss");
  g.get("enabled", &c.gnss_enabled).get("device", &c.gnss_device).get("baud", &c.gnss_baud);
  g.get("rate_hz", &c.gnss_rate_hz).get("configure", &c.gnss_configure);
  if (!(c.gnss_rate_hz > 0 && c.gnss_rate_hz <= 10))
    g.record_error("rate_hz", "expected (0, 10] Hz (u-blox M8T)");

  core::ConfigMap ex = root.child("extrinsics");
  read_pose16(ex, "T_imu_cam", &c.T_imu_cam);
  ex.get("gnss_antenna_imu_m", &c.gnss_antenna_imu_m).get("mag_hard_iron_uT", &c.mag_hard_iron_uT);
  root.get("sysfs_root", &c.sysfs_root);

  if (c.imu == ImuKind::kA9 && !c.a9_enabled) {
    root.record_error("imu", "'a9' feeds the estimator but a9.enabled is false");
  }
  if (c.imu == ImuKind::kZed && !c.zed_sensors && c.camera.enabled) {
    root.record_error("imu", "'zed' feeds the estimator but zed_sensors.enabled is false");
  }
  if (core::Status st = doc->finish(); !st.ok()) return st;
  return c;
}

core::Expected<HwConfig> load_hw_config(const std::string& path) {
  std::string text;
  if (core::Status st = core::read_file(path, &text); !st.ok()) return st;
  return parse_hw_config(text, path);
}

}  // namespace hwr::hal::hw
