// libFuzzer target: the ZED 2i's two parsers of outside bytes. First byte even: the rest is one HID
// input report (parse_zed_sensor_report, then its IMU and magnetometer samples); odd: the rest is an
// SN<serial>.conf text (parse_zed_calibration at the eye width the first byte selects). Invariants:
// a parsed report's values are finite and within the sensors' full scales; a parsed rig has positive
// focal lengths and baseline and a rotation. Seeds: make_zed_seeds.cpp.

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string_view>

#include "hwr/hal/hw/zed_calibration.hpp"
#include "hwr/hal/hw/zed_sensor_report.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  const uint8_t selector = data[0];
  ++data;
  --size;
  using namespace hwr::hal::hw;
  if ((selector & 1) == 0) {
    auto r = parse_zed_sensor_report(data, size);
    if (!r.ok()) return 0;
    const hwr::hal::ImuSample s = to_imu_sample(*r, 0);
    if (!s.accel_mps2.allFinite() || s.accel_mps2.cwiseAbs().maxCoeff() > 8 * 9.8189 + 1e-9) std::abort();
    if (!s.gyro_radps.allFinite() || s.gyro_radps.cwiseAbs().maxCoeff() > 1000.0 * M_PI / 180.0 + 1e-9)
      std::abort();
    if (r->t_imu_ns < 0) std::abort();
    auto m = to_mag_sample(*r, 0);
    if (m && (!m->field_uT.allFinite() || r->mag_state != ZedMagState::kNew)) std::abort();
    return 0;
  }
  static const int kWidths[4] = {2208, 1920, 1280, 672};
  const int width = kWidths[(selector >> 1) & 3];
  auto rig =
      parse_zed_calibration(std::string_view(reinterpret_cast<const char*>(data), size), width, "fuzz.conf");
  if (!rig.ok()) return 0;
  if (!(rig->left.fx > 0 && rig->right.fy > 0 && rig->T_left_right.translation().x() > 0)) std::abort();
  const Eigen::Matrix3d R = rig->T_left_right.linear();
  if (!R.allFinite() || (R.transpose() * R - Eigen::Matrix3d::Identity()).norm() > 1e-6) std::abort();
  return 0;
}
