#pragma once
// One GNSS solution (the fields of u-blox NAV-PVT the pipeline uses). fix_type follows NAV-PVT:
// 0 no fix, 2 2D, 3 3D. Geodetic coordinates on WGS-84; height above the ellipsoid.

#include <cstdint>

namespace hwr::hal {

struct GnssFix {
  int64_t t_ns = 0;
  uint8_t fix_type = 0;
  uint8_t num_sv = 0;
  double lat_deg = 0;
  double lon_deg = 0;
  double height_m = 0;
  double h_acc_m = 0;  // 1-sigma horizontal accuracy estimate
  double v_acc_m = 0;

  bool has_3d_fix() const { return fix_type >= 3; }
};

}  // namespace hwr::hal
